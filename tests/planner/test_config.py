"""The planner's configuration as data: dotted overrides, files, presets, and what a run records."""

from __future__ import annotations

import json

import pytest

from cpkb.cli import main
from planner.config import (
    ConfigError,
    PlanConfig,
    load_file,
    method_config,
    parse_assignments,
    typed_overrides,
)
from planner.run import PlanRequest, run_plan


def test_dotted_overrides_are_parsed_by_the_fields_types():
    config = PlanConfig().with_overrides(
        parse_assignments(["cp_bo.lookahead=false", "search.pw_k=10", "cp_bo.batch= 2 "])
    )
    assert config.cp_bo.lookahead is False and config.cp_bo.batch == 2
    assert config.search.pw_k == 10.0 and isinstance(config.search.pw_k, float)
    assert config.search.ucb_c == PlanConfig().search.ucb_c  # the rest is left alone
    assert PlanConfig().cp_bo.lookahead is True  # frozen: the original is unchanged


def test_two_spellings_of_one_variant_compare_equal():
    assert typed_overrides({"cp_bo.lookahead": "no", "search.pw_k": "10"}) == typed_overrides(
        {"search.pw_k": 10, "cp_bo.lookahead": False}
    )


def test_a_misspelled_key_names_the_known_keys():
    with pytest.raises(ConfigError) as caught:
        parse_assignments(["cp_bo.lookahaed=false"])
    message = str(caught.value)
    assert "'cp_bo.lookahaed'" in message and "cp_bo.lookahead" in message
    assert "search.pw_k" in message and "knowledge.refresh_rollouts" in message
    for key in ("search", "nowhere.pw_k", "search.", "cp_bo.batch.size"):
        with pytest.raises(ConfigError, match="unknown configuration key"):
            PlanConfig().with_overrides({key: 1})


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"cp_bo.batch": "two"}, "cp_bo.batch takes a int"),
        ({"cp_bo.lookahead": "maybe"}, "cp_bo.lookahead takes a bool"),
        ({"cp_bo.batch": True}, "cp_bo.batch takes a int"),
        ({"search.pw_k": [1]}, "search.pw_k takes a float"),
        ({"cp_bo.batch": 2.5}, "cp_bo.batch takes a int"),
        ({"cp_bo.batch": 0}, "cp_bo.batch must be at least 1"),
        ({"search.outlook_ratio": 0.5}, "search.outlook_ratio must be at least 1"),
        ({"knowledge.match_chunk": 5000}, "at most 1000"),
        ({"knowledge.prior_counts": -1.0}, "knowledge.prior_counts must be at least 0"),
    ],
)
def test_a_value_of_the_wrong_type_or_range_is_refused(overrides, message):
    with pytest.raises(ConfigError, match=message):
        PlanConfig().with_overrides(overrides)


def test_an_assignment_needs_an_equals_sign():
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_assignments(["cp_bo.lookahead"])


def test_files_hold_nested_or_dotted_keys_and_a_recorded_config_reads_back(tmp_path):
    nested = tmp_path / "variant.yaml"
    nested.write_text("cp_bo:\n  lookahead: false\n  batch: 2\nsearch.pw_k: 10\n")
    config = PlanConfig().with_overrides(load_file(nested))
    assert (config.cp_bo.lookahead, config.cp_bo.batch, config.search.pw_k) == (False, 2, 10.0)
    recorded = tmp_path / "config.json"
    recorded.write_text(json.dumps(config.to_dict()))
    assert PlanConfig().with_overrides(load_file(recorded)) == config
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    assert load_file(empty) == {}


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("bad.yaml", "cp_bo: [unclosed", "not valid YAML"),
        ("bad.json", "{", "not valid JSON"),
        ("list.yaml", "- cp_bo.batch\n", "must hold a mapping"),
        ("typo.yaml", "cp_bo:\n  bach: 2\n", "unknown configuration key 'cp_bo.bach'"),
    ],
)
def test_a_bad_file_is_a_clear_error(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_file(path)
    with pytest.raises(ConfigError, match="cannot read"):
        load_file(tmp_path / "missing.yaml")


def test_the_paper_preset_is_cp_bo_with_every_extension_off_whatever_was_set():
    asked = PlanConfig().with_overrides(
        {
            "cp_bo.lookahead": True,
            "search.pw_k": 7,
            "search.restart_unit": 16,
            "knowledge.relative_pairs": True,
            "knowledge.periodic_headings": True,
        }
    )
    paper = method_config("cp-bo-paper", asked)
    assert not (paper.cp_bo.lookahead or paper.cp_bo.prematch or paper.cp_bo.continuations)
    assert paper.cp_bo.batch == 1
    search = paper.search
    assert not (search.outlook_widening or search.outlook_selection or search.hopeless_widening)
    assert search.restart_unit == 0
    knowledge = paper.knowledge
    assert not (knowledge.square_grasps or knowledge.grasp_symmetry)
    assert not (knowledge.relative_pairs or knowledge.periodic_headings)
    assert search.pw_k == 7.0  # a knob the paper does not fix stays the caller's
    assert method_config("cp-bo", asked) == asked
    assert PlanRequest("analytic:desk", "cp-bo-paper", 0).config == method_config("cp-bo-paper")


def test_each_run_records_its_whole_configuration_and_uses_it():
    sparse = PlanConfig().with_overrides({"quasi_random.candidates_per_dim": 1})
    plain = [run_plan("analytic:desk", "quasi-random", seed) for seed in range(3)]
    changed = [run_plan("analytic:desk", "quasi-random", seed, config=sparse) for seed in range(3)]
    assert plain[0].config == PlanConfig().to_dict()
    assert changed[0].to_json()["config"]["quasi_random"]["candidates_per_dim"] == 1
    assert set(changed[0].config) == set(PlanConfig().to_dict())
    assert [r.bindings for r in plain] != [r.bindings for r in changed]
    again = run_plan(PlanRequest("analytic:desk", "quasi-random", 0, config=sparse))
    assert (again.rollouts, again.bindings) == (changed[0].rollouts, changed[0].bindings)


def test_run_plan_takes_a_request_or_its_fields_not_both():
    with pytest.raises(TypeError, match="not both"):
        run_plan(PlanRequest("analytic:desk", "quasi-random", 0), max_rollouts=5)
    with pytest.raises(TypeError, match="method and a seed"):
        run_plan("analytic:desk")
    with pytest.raises(ValueError, match="unknown method"):
        PlanRequest("analytic:desk", "cp-bo-papr", 0)


def test_cpkb_plan_takes_set_and_config(tmp_path, capsys):
    variant = tmp_path / "variant.yaml"
    variant.write_text("search:\n  pw_k: 5\n  ucb_c: 0.3\n")
    argv = ["plan", "--task", "analytic:desk", "--method", "quasi-random", "--json"]
    code = main([*argv, "--config", str(variant), "--set", "search.pw_k=6"])
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0
    assert (result["config"]["search"]["pw_k"], result["config"]["search"]["ucb_c"]) == (6.0, 0.3)


def test_cpkb_plan_names_a_misspelled_knob(capsys):
    argv = ["plan", "--task", "analytic:desk", "--method", "quasi-random", "--quiet"]
    assert main([*argv, "--set", "search.pwk=5"]) == 2
    err = capsys.readouterr().err
    assert "unknown configuration key 'search.pwk'" in err and "search.pw_k" in err

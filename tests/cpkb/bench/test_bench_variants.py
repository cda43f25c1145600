"""Variants: a named method under fixed knobs, defined in a file, run beside the plain methods
on the same seeds, each run recording what it ran."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cpkb.bench.app import known_methods
from cpkb.bench.scenarios import Scenario, expand
from cpkb.bench.variants import load_variants, parse_variants
from planner.config import ConfigError

REPO = Path(__file__).resolve().parents[3]


def _runs(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]


def test_the_shipped_ablation_file_loads_and_every_variant_runs_a_known_method() -> None:
    variants = load_variants(REPO / "benchmarks" / "ablation.yaml", known_methods())
    assert {"no-lookahead", "transfer-no-prematch"} <= set(variants)
    assert variants["no-lookahead"].overrides == (
        ("cp_bo.continuations", False),
        ("cp_bo.lookahead", False),
    )
    transfer = expand(["regrasp"], ["transfer-no-prematch"], [3], variants)[0]
    assert transfer.key == ("regrasp", "transfer-no-prematch", 3)
    assert (transfer.runs, transfer.sampler) == ("cp-bo-transfer", "cp-bo")
    assert transfer.predecessors == ("deskP", "desk")
    assert transfer.overrides == (("cp_bo.prematch", False),)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"variants": {"x": {"method": "cp-bo", "set": {"cp_bo.bach": 2}}}}, "bach"),
        ({"variants": {"x": {"method": "cp-bo", "set": {"cp_bo.batch": 0}}}}, "at least"),
        ({"variants": {"x": {"method": "cp-boo"}}}, "unknown method"),
        ({"variants": {"cp-bo": {"method": "cp-bo"}}}, "must be new"),
        ({"variants": {"a,b": {"method": "cp-bo"}}}, "without commas"),
        ({"variants": {"x": {"method": "cp-bo", "knobs": {}}}}, "takes `method` and `set`"),
        ({"variant": {}}, "a mapping"),
    ],
)
def test_a_wrong_variant_is_refused_naming_it(data: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_variants(data, known_methods())


def test_a_scenario_without_a_variant_runs_its_own_method() -> None:
    plain = Scenario("pack", "cp-bo-paper-transfer", 0)
    assert (plain.runs, plain.sampler, plain.overrides) == (
        "cp-bo-paper-transfer",
        "cp-bo-paper",
        (),
    )


@pytest.mark.slow
def test_cpkb_bench_runs_variants_beside_plain_methods(tmp_path: Path) -> None:
    variants = tmp_path / "variants.yaml"
    variants.write_text(
        "variants:\n  few-candidates:\n    method: quasi-random\n"
        "    set: {quasi_random.candidates_per_dim: 2}\n"
    )
    out = tmp_path / "out"
    command = [
        sys.executable, "-m", "cpkb", "bench", "--tasks", "analytic:desk",
        "--methods", "quasi-random,few-candidates", "--seeds", "2", "--workers", "1",
        "--max-rollouts", "300", "--out", str(out), "--quiet", "--variants", str(variants),
    ]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    runs = {(r["method"], r["seed"]): r for r in _runs(out)}
    assert set(runs) == {(m, s) for m in ("quasi-random", "few-candidates") for s in (0, 1)}
    for seed in (0, 1):
        variant, plain = runs[("few-candidates", seed)], runs[("quasi-random", seed)]
        assert variant["base_method"] == "quasi-random" and variant["sampler"] == "quasi-random"
        assert variant["overrides"] == {"quasi_random.candidates_per_dim": 2}
        assert variant["config"]["quasi_random"]["candidates_per_dim"] == 2
        assert plain["config"]["quasi_random"]["candidates_per_dim"] == 10
    assert "| analytic:desk | few-candidates | 2 |" in (out / "summary.md").read_text()


def test_cpkb_bench_names_a_broken_variants_file(tmp_path: Path) -> None:
    from cpkb.cli import main

    broken = tmp_path / "variants.yaml"
    broken.write_text("variants:\n  x: {method: cp-bo, set: {search.pw_kk: 1}}\n")
    argv = ["bench", "--tasks", "analytic:desk", "--methods", "x", "--seeds", "1"]
    assert main([*argv, "--out", str(tmp_path / "out"), "--variants", str(broken)]) == 2
    assert not (tmp_path / "out").exists()

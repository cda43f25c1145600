"""Planner knobs in the bench: every run gets them and records its whole configuration, the
output directory pins them, and `cp-bo-paper` is a method like any other."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cpkb.bench.app import plan_run
from cpkb.bench.results import BenchConfigError
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import Scenario


def _runs(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]


@pytest.mark.slow
def test_the_knobs_reach_every_run_and_are_pinned(tmp_path: Path) -> None:
    out = tmp_path / "out"
    scenarios = [Scenario("analytic:desk", "quasi-random", s) for s in range(2)]
    knobs = {"search.pw_k": 5.0, "quasi_random.candidates_per_dim": 3}
    outcome = run_bench(scenarios, out, plan_run, workers=1, max_rollouts=200, config=knobs)
    assert outcome.finished == 2 and outcome.errors == 0, outcome.error_messages
    for record in _runs(out):
        assert record["config"]["search"]["pw_k"] == 5.0
        assert record["config"]["quasi_random"]["candidates_per_dim"] == 3
        assert record["config"]["cp_bo"]["lookahead"] is True  # the rest: the defaults
    assert json.loads((out / "bench.json").read_text())["config"] == knobs
    with pytest.raises(BenchConfigError, match="config"):
        run_bench(scenarios, out, plan_run, workers=1, max_rollouts=200, config={})


@pytest.mark.slow
def test_a_directory_from_before_the_knobs_were_pinned_means_none_set(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "bench.json").write_text(json.dumps({"max_rollouts": 50, "predecessor_rollouts": 30}))
    scenarios = [Scenario("analytic:desk", "quasi-random", 0)]
    assert run_bench(scenarios, out, plan_run, workers=1, max_rollouts=50).finished == 1
    with pytest.raises(BenchConfigError):
        run_bench(scenarios, out, plan_run, workers=1, max_rollouts=50, config={"search.ucb_c": 1})


@pytest.mark.slow
def test_cpkb_bench_runs_cp_bo_paper_with_set_knobs(tmp_path: Path) -> None:
    out = tmp_path / "out"
    command = [
        sys.executable, "-m", "cpkb", "bench", "--tasks", "analytic:desk",
        "--methods", "cp-bo-paper,cp-bo", "--seeds", "1", "--workers", "1",
        "--max-rollouts", "300", "--out", str(out), "--quiet", "--set", "search.pw_k=10",
    ]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    runs = {r["method"]: r for r in _runs(out)}
    assert set(runs) == {"cp-bo-paper", "cp-bo"} and all(r["solved"] for r in runs.values())
    paper, extended = runs["cp-bo-paper"]["config"], runs["cp-bo"]["config"]
    assert paper["search"]["pw_k"] == extended["search"]["pw_k"] == 10.0
    assert paper["cp_bo"]["prematch"] is False and extended["cp_bo"]["prematch"] is True
    assert "| analytic:desk | cp-bo-paper | 1 |" in (out / "summary.md").read_text()


def test_cpkb_bench_names_a_misspelled_knob(tmp_path: Path) -> None:
    from cpkb.cli import main

    argv = ["bench", "--tasks", "analytic:desk", "--methods", "quasi-random", "--seeds", "1"]
    assert main([*argv, "--out", str(tmp_path / "out"), "--set", "cp_bo.bach=2"]) == 2
    assert not (tmp_path / "out").exists()


def test_the_surrogate_settings_away_from_their_defaults_are_what_a_bench_pins(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from server.settings import surrogate_overrides

    monkeypatch.setenv("CPKB_SURROGATE__BALANCE_CLASSES", "false")
    monkeypatch.setenv("CPKB_SURROGATE__OPTIMIZER__GENERATIONS", "3")
    monkeypatch.setenv("CPKB_PORT", "8123")  # not a surrogate setting: results do not depend on it
    assert surrogate_overrides() == {
        "surrogate.balance_classes": False,
        "surrogate.optimizer.generations": 3,
    }


@pytest.mark.slow
def test_the_embedded_services_settings_are_pinned_with_the_results(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from server.settings import surrogate_overrides

    monkeypatch.setenv("CPKB_SURROGATE__BALANCE_CLASSES", "false")
    service = surrogate_overrides()
    out = tmp_path / "out"
    scenarios = [Scenario("analytic:desk", "quasi-random", 0)]
    done = run_bench(scenarios, out, plan_run, workers=1, max_rollouts=50, service=service)
    assert done.finished == 1
    assert json.loads((out / "bench.json").read_text())["service"] == service
    with pytest.raises(BenchConfigError, match="service"):
        run_bench(scenarios, out, plan_run, workers=1, max_rollouts=50)


@pytest.mark.slow
def test_where_the_embedded_service_ran_is_pinned_with_the_results(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Off the workers' cores by default; a rerun on shared cores is another variant."""
    from cpkb.cli import main

    for name in [k for k in os.environ if k.startswith("CPKB_SURROGATE__")]:
        monkeypatch.delenv(name)
    out = tmp_path / "out"
    argv = ["bench", "--tasks", "analytic:desk", "--methods", "quasi-random", "--workers", "1"]
    assert main([*argv, "--seeds", "1", "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "bench.json").read_text())["service"] == {"cpu_cores": "spare"}
    shared = [*argv, "--seeds", "2", "--out", str(out), "--quiet", "--service-cores", "shared"]
    assert main(shared) == 2
    assert len(_runs(out)) == 1
    old = tmp_path / "old"
    old.mkdir()
    (old / "bench.json").write_text(json.dumps({"max_rollouts": 2000, "predecessor_rollouts": 30}))
    before = [*argv, "--seeds", "1", "--out", str(old), "--quiet", "--service-cores", "shared"]
    assert main(before) == 0

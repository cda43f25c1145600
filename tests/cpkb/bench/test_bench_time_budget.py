"""`cpkb bench --time-budget`: each target run gets the budget and records it, the directory pins
it, and the summary gives the success rate at the budget and the mean time to the first binding
with an unsolved run counted at the budget (as eTAMP's table does)."""

from __future__ import annotations

from pathlib import Path

import pytest

from cpkb.bench.app import plan_run
from cpkb.bench.results import BenchConfigError, ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import expand
from cpkb.bench.stats import solved_at_budget, summarize, time_metric


def _record(method: str, seed: int, solved: bool, wall_s: float, budget: float | None) -> dict:
    return {
        "task": "desk",
        "method": method,
        "seed": seed,
        "rollouts": 10 if solved else 2000,
        "solved": solved,
        "wall_s": wall_s,
        "time_budget_s": budget,
    }


def test_unsolved_and_late_runs_count_at_the_budget() -> None:
    records = [
        _record("quasi-random", 0, True, 20.0, 60.0),
        _record("quasi-random", 1, False, 60.4, 60.0),  # stopped by the budget
        _record("quasi-random", 2, False, 12.0, 60.0),  # rollout cap before the budget
        _record("quasi-random", 3, True, 61.0, 60.0),  # its last rollout ended past the budget
    ]
    assert [solved_at_budget(r) for r in records] == [True, False, False, False]
    assert [time_metric(r) for r in records] == [20.0, 60.0, 60.0, 60.0]
    (row,) = summarize(records)
    assert row.solved_rate == pytest.approx(0.25)
    assert row.wall_mean_s == pytest.approx((20 + 3 * 60) / 4)


def test_without_a_budget_a_run_counts_its_own_time() -> None:
    records = [_record("cp-bo", 0, True, 5.0, None), _record("cp-bo", 1, False, 30.0, None)]
    (row,) = summarize(records)
    assert row.solved_rate == pytest.approx(0.5) and row.wall_mean_s == pytest.approx(17.5)


@pytest.mark.slow
def test_a_tiny_budget_leaves_every_run_unsolved_at_the_budget(tmp_path: Path) -> None:
    out = tmp_path / "out"
    scenarios = expand(["analytic:desk"], ["quasi-random"], range(2))
    outcome = run_bench(scenarios, out, plan_run, workers=1, max_rollouts=500, time_budget_s=1e-9)
    assert (outcome.finished, outcome.errors) == (2, 0)
    records = ResultStore(out).records()
    assert all(r["time_budget_s"] == 1e-9 and r["timed_out"] for r in records)
    assert all(not r["solved"] and r["rollouts"] == 0 for r in records)
    (row,) = summarize(records)
    assert row.solved_rate == 0.0 and row.wall_mean_s == pytest.approx(1e-9)
    with pytest.raises(BenchConfigError, match="time_budget_s"):
        run_bench(scenarios, out, plan_run, workers=1, max_rollouts=500, time_budget_s=60.0)

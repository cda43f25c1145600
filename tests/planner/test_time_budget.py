"""A budget in seconds beside the one in rollouts: the search starts no rollout after its
deadline, a run records its budget and that it ran out, and `cpkb plan --time-budget` sets it.
Budgets are chosen so that no clock decides the outcome: one already past, or one no run
reaches."""

from __future__ import annotations

import json
import time

import pytest

from cpkb.cli import main
from planner.run import PlanRequest, run_plan
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers.quasi_random import QuasiRandomSampler


def test_a_deadline_already_past_starts_no_rollout() -> None:
    search = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=3)
    outcome = search.run(500, deadline=time.perf_counter())
    assert outcome.timed_out and not outcome.solved
    assert outcome.rollouts_spent == 0


def test_a_deadline_no_run_reaches_changes_nothing() -> None:
    plain = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=3).run(500)
    timed = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=3).run(
        500, deadline=time.perf_counter() + 1e6
    )
    assert plain.solved and not timed.timed_out
    assert (timed.rollouts, timed.bindings) == (plain.rollouts, plain.bindings)


def test_a_tiny_budget_stops_the_run_and_records_it_unsolved() -> None:
    result = run_plan("analytic:desk", "quasi-random", 1, max_rollouts=500, time_budget_s=1e-9)
    assert not result.solved and result.timed_out
    assert result.rollouts == 0 and result.time_budget_s == 1e-9
    assert "time budget reached" in result.notes
    assert result.to_json()["time_budget_s"] == 1e-9


def test_a_run_within_its_budget_records_the_budget_and_no_timeout() -> None:
    result = run_plan("analytic:desk", "quasi-random", 1, max_rollouts=500, time_budget_s=1e6)
    assert result.solved and not result.timed_out and result.time_budget_s == 1e6


@pytest.mark.parametrize("budget", [0.0, -1.0])
def test_a_budget_must_be_above_zero(budget: float) -> None:
    with pytest.raises(ValueError, match="time_budget_s"):
        PlanRequest("analytic:desk", "quasi-random", 0, time_budget_s=budget)


def test_cpkb_plan_takes_a_time_budget(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["plan", "--task", "analytic:desk", "--method", "quasi-random", "--json"]
    code = main([*argv, "--time-budget", "0.000000001"])
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 1 and result["timed_out"] and result["time_budget_s"] == 1e-9
    code = main([*argv, "--time-budget", "2h"])
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and result["solved"] and result["time_budget_s"] == 7200


def test_a_bad_time_budget_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["plan", "--task", "analytic:desk", "--time-budget", "0"])
    assert exit_info.value.code == 2
    assert "above zero" in capsys.readouterr().err

"""benchmarks/rollout_cpu.py: the planner's CPU time per rollout, against the baseline's."""

from __future__ import annotations

import pytest
from script_support import load_script

rollout_cpu = load_script("rollout_cpu")


def test_ratios_are_per_rollout_against_the_baseline() -> None:
    totals = {
        "quasi-random-restarts": [2.0, 400.0, 20.0, 8.0],
        "cp-bo": [2.0, 200.0, 30.0, 8.0],
    }
    table = rollout_cpu.table(totals, ["quasi-random-restarts", "cp-bo"])
    assert "| quasi-random-restarts | 2 | 400 | 50.0 | 20.0 | - | - |" in table
    assert "| cp-bo | 2 | 200 | 150.0 | 40.0 | 3.00 | 2.00 |" in table


def test_a_suite_stands_for_its_targets(tmp_path) -> None:
    for name in ("ws00/pack.yaml", "ws00/pack_pre1.yaml", "ws00/workspace.yaml", "ws01/desk.yaml"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("")
    found = rollout_cpu._targets(str(tmp_path))
    assert [p.relative_to(tmp_path).as_posix() for p in found] == [
        "ws00/pack.yaml",
        "ws01/desk.yaml",
    ]


def test_no_tasks_is_a_clear_error(capsys) -> None:
    assert rollout_cpu.main(["--tasks", ""]) == 2
    assert "no tasks" in capsys.readouterr().err


@pytest.mark.slow
def test_each_method_runs_its_rollouts_and_is_measured(capsys) -> None:
    args = ["--tasks", "analytic:desk", "--methods", "quasi-random-restarts,cp-bo"]
    assert rollout_cpu.main([*args, "--seeds", "3-3", "--rollouts", "4"]) == 0
    out = capsys.readouterr().out
    assert "| quasi-random-restarts | 1 | 4 |" in out
    assert "| cp-bo | 1 | 4 |" in out

"""benchmarks/rollout_cost.py: the cost per rollout actually run, against the baseline's."""

from __future__ import annotations

import pytest
from script_support import load_script

rollout_cost = load_script("rollout_cost")


def _run(method: str, rollouts: int, wall: float, sim: float, suggest: float = 0.0) -> dict:
    return {
        "task": "analytic:desk",
        "method": method,
        "seed": 0,
        "rollouts": rollouts,
        "solved": False,
        "wall_s": wall,
        "sim_s": sim,
        "kb_parts": {"suggest": suggest, "match": 1.0} if suggest else {},
        "suggest_cpu_s": suggest / 10,
    }


def test_a_run_stopped_by_its_budget_counts_the_rollouts_it_ran() -> None:
    records = [
        _run("quasi-random-restarts", 500, 60.0, 55.0),
        _run("quasi-random-restarts", 100, 10.0, 9.0),
        _run("cp-bo", 150, 60.0, 30.0, suggest=20.0),
    ]
    cells = rollout_cost.per_rollout(records)
    qr, guided = (
        cells[("analytic:desk", "quasi-random-restarts")],
        cells[("analytic:desk", "cp-bo")],
    )
    assert qr["rollouts"] == 600 and qr["wall_s"] == pytest.approx(1000 * 70 / 600)
    assert guided["wall_s"] == pytest.approx(400.0)
    assert guided["suggest_s"] == pytest.approx(1000 * 20 / 150)
    assert guided["rest_s"] == pytest.approx(1000 * (60 - 30 - 20 - 1) / 150)
    shown = rollout_cost.table(cells, ["quasi-random-restarts", "cp-bo"])
    assert f"| {400 / qr['wall_s']:.2f} |" in shown

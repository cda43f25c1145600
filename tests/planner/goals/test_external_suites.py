"""The external suites load as goal-only targets, and K* finds plans for each."""

from __future__ import annotations

from pathlib import Path

from planner.goals.pddl import top_plans
from planner.tasks import load_task
from planner.tasks.suites import suite_targets

EXTERNAL = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "external"


def test_every_external_target_is_posed_by_its_goal_alone_and_has_plans() -> None:
    targets = suite_targets(EXTERNAL)
    names = [p.stem for p in targets]
    assert names == ["blocked", "hanoi3", "hanoi4", "nonmono", "packed", "regrasp", "unpack3"]
    fewest = {}
    for path in targets:
        task = load_task(str(path))
        assert task.layers == () and task.role == "target"
        plans = top_plans(task, 40)
        fewest[path.stem] = len(plans[0].moves)
    # One move per goal body at least (the red block of nonmono stands where its goal is), and
    # 2^n - 1 moves for Hanoi's n discs.
    assert fewest == {
        **{"blocked": 1, "hanoi3": 7, "hanoi4": 15, "nonmono": 1},
        **{"packed": 5, "regrasp": 1, "unpack3": 3},
    }

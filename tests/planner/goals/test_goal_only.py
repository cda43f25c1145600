"""Goal-only tasks: skeletons from K* over cpkb's operators as PDDL, searched in turns; the
`blocked` task (the goal block walled in on three sides, a blocker before the open side) posed
by its goal alone is solved with the blocker moved first."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_support import cpkb_in_process

from planner.goals.pddl import Move, Plan, redundant, top_plans
from planner.goals.search import PROGRESS_FLOOR, TURN, Branch, priority
from planner.goals.skeletons import plan_layers, skeleton_task
from planner.run import run_plan
from planner.sim.world import PyBulletWorld
from planner.tasks import load_task

ROOT = Path(__file__).resolve().parents[3]
BLOCKED = ROOT / "benchmarks" / "suites" / "external" / "blocked" / "blocked.yaml"


def test_k_star_gives_the_direct_plan_first_and_the_blocker_moves_among_the_next() -> None:
    task = load_task(str(BLOCKED))
    assert task.layers == ()
    plans = top_plans(task, 40)
    assert plans[0].moves == (Move("block", "goal"),)
    costs = [p.cost for p in plans]
    assert costs == sorted(costs)
    assert Plan((Move("blocker", "left"), Move("block", "goal")), 4.0) in plans
    assert not any(redundant(task, p) for p in plans)


def test_redundant_plans_are_dropped() -> None:
    task = load_task(str(BLOCKED))
    assert redundant(task, Plan((Move("blocker", "front"), Move("block", "goal")), 4.0))
    assert redundant(task, Plan((Move("block", "goal"), Move("blocker", "left")), 4.0))
    assert not redundant(task, Plan((Move("block", "left"), Move("block", "goal")), 4.0))


def test_a_plan_becomes_the_skeleton_a_task_file_would_give() -> None:
    task = load_task(str(BLOCKED))
    layers = plan_layers(task, Plan((Move("blocker", "left"), Move("block", "goal")), 4.0))
    text = [f"{c.name}({', '.join(c.args)})" for layer in layers for c in layer.calls]
    assert text[:4] == [
        "Sample-grasp(blocker)",
        "Inv-kin(blocker, before_stall, #dir1)",
        "Plan-motion(config0, #config1g)",
        "Move-Pick(blocker, #traj1g)",
    ]
    assert text[8:10] == ["Sample-grasp(block)", "Inv-kin(block, in_stall, #dir2)"]
    assert text[-3:] == [
        "Inv-kin(block, #pose2, #dir2)",
        "Plan-motion(#config2g, #config2p)",
        "Move-Place(block, #traj2p)",
    ]


def test_a_skeleton_failing_early_yields_and_one_that_comes_close_is_revisited() -> None:
    direct = Plan((Move("block", "goal"),), 2.0)
    clearing = Plan((Move("blocker", "left"), Move("block", "goal")), 4.0)
    failing = Branch(direct, 0, spent=TURN, progress=0.3)
    fresh = Branch(clearing, 1)
    # Unblamed, the longer plan waits for the cheaper one to have spent more.
    assert priority(fresh, 1, set()) > priority(failing, 1, set())
    # Once a failure named the blocker, a plan that moves it first is as cheap as the direct one.
    assert priority(fresh, 1, {"blocker"}) < priority(failing, 1, {"blocker"})
    close = Branch(clearing, 1, spent=5 * TURN, progress=0.9)
    assert priority(close, 1, set()) < priority(
        Branch(direct, 0, spent=TURN, progress=0.1), 1, set()
    )
    assert priority(Branch(direct, 0, exhausted=True), 1, set()) == float("inf")
    assert PROGRESS_FLOOR > 0


def test_blocked_posed_by_its_goal_alone_is_solved_with_the_blocker_moved_first() -> None:
    result = run_plan(str(BLOCKED), "quasi-random", 0, max_rollouts=300)
    assert result.solved, result.notes
    # Progress is the deepest rollout's share of its skeleton's layers: all of them, solved.
    assert result.best_depth == 1.0
    solved_by = next(n for n in result.notes if n.startswith("solved by skeleton"))
    assert "(move blocker to " in solved_by and solved_by.endswith(", then block to goal)")
    task = load_task(str(BLOCKED))
    index = int(solved_by.split()[3]) - 1
    world = PyBulletWorld(skeleton_task(task, top_plans(task, 40)[index]), seed=0)
    try:
        state = world.initial_state()
        for i in range(len(world.skeleton.transitions)):
            out = world.transition(i, result.bindings, state)
            assert out.ok, out.failed
            state = out.state
        assert world.scene.in_region("block", "goal")
    finally:
        world.close()


def test_plan_solves_a_goal_only_task_from_the_command_line(
    capfd: pytest.CaptureFixture[str],
) -> None:
    out = cpkb_in_process(
        capfd,
        "plan",
        "--task",
        str(BLOCKED),
        "--method",
        "quasi-random",
        "--seed",
        "1",
        "--max-rollouts",
        "300",
        "--json",
        "--quiet",
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["solved"] and result["task"] == "blocked"
    assert any("(move blocker to " in note for note in result["notes"])


def test_a_time_budget_stops_the_turns() -> None:
    # K* and the scene alone take longer than the budget: no turn starts.
    result = run_plan(str(BLOCKED), "quasi-random", 0, time_budget_s=0.001)
    assert not result.solved and result.rollouts == 0
    assert "time budget reached" in result.notes
    assert any(
        note.endswith("before the first turn (K*, the scene, the knowledge base)")
        for note in result.notes
    )

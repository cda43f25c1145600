"""A second run in the same knowledge base starts from the skeleton an earlier run solved: the
found binding lists are stored by task and skeleton digest, and the scheduler gives the skeleton
with one the first turn, a single rollout that follows it."""

from __future__ import annotations

from pathlib import Path

from contract.bindings import BindingIn
from planner.goals.pddl import Move, top_plans
from planner.goals.search import (
    TURN,
    Branch,
    next_branch,
    priority,
    solved_before,
    stored_skeletons,
)
from planner.goals.skeletons import skeleton_task
from planner.knowledge.found import skeleton_digest
from planner.knowledge.memory import InMemoryKnowledge
from planner.tasks import build_skeleton, load_task

BLOCKED = (
    Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "external" / "blocked"
) / "blocked.yaml"


def test_the_skeleton_an_earlier_run_solved_is_found_and_run_first() -> None:
    task = load_task(str(BLOCKED))
    plans = top_plans(task, 40)
    solved = next(
        i
        for i, p in enumerate(plans)
        if p.moves[0] == Move("blocker", "left") and len(p.moves) == 2
    )
    memory = InMemoryKnowledge()
    memory.create_kb("kb")
    assert stored_skeletons(memory, "kb", task) == set()
    assert solved_before(set(), task, plans) == [False] * len(plans)
    digest = skeleton_digest(build_skeleton(skeleton_task(task, plans[solved])))
    memory.add_binding(
        "kb",
        BindingIn(
            task=task.name, skeleton=digest, run="earlier", rollout=3, bindings={"#dir1": "front"}
        ),
    )
    memory.add_binding(
        "kb",
        BindingIn(
            task="other", skeleton="0" * 64, run="earlier", rollout=3, bindings={"#dir1": "top"}
        ),
    )
    stored = stored_skeletons(memory, "kb", task)
    assert stored == {digest}
    marks = solved_before(stored, task, plans)
    assert marks == [i == solved for i in range(len(plans))]
    branches = [
        Branch(p, i, solved_before=m) for i, (p, m) in enumerate(zip(plans, marks, strict=True))
    ]
    first = next_branch(branches, 0, len(plans[0].moves), set())
    assert first.index == solved
    # Without the stored list the cheapest plan goes first, as before.
    cold = [Branch(p, i) for i, p in enumerate(plans)]
    assert next_branch(cold, 0, len(plans[0].moves), set()).index == 0
    # Its one following rollout failed: it keeps the next turn, then yields as any other.
    first.spent = 1
    assert priority(first, 1, set()) == 0.0
    first.spent, first.progress = 1 + TURN, 0.1
    assert priority(first, 1, set()) > 0.0

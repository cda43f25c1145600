"""Stacking: `On(body, other_body)` makes the top face of a movable body a placement region,
wherever that body has been moved; the planner solves a real stacking task in PyBullet, and
failure graphs name the body under like any region, placed where its own decision put it."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner.failures.graphs import failure_graph
from planner.run import run_plan
from planner.sim import load_world
from planner.tasks import load_task
from planner.tasks.schema import TaskError
from planner.world import CheckResult

STACK = Path(__file__).with_name("stack.yaml")


def test_the_planner_stacks_a_block_on_one_it_moved_first() -> None:
    result = run_plan(str(STACK), "quasi-random", 0, max_rollouts=300)
    assert result.solved, result
    world = load_world(STACK, seed=0)
    try:
        state = world.initial_state()
        for index in range(len(world.skeleton.transitions)):
            out = world.transition(index, result.bindings, state)
            assert out.ok, out.failed
            state = out.state
        assert world.scene.in_region("base", "region3")
        assert world.scene.in_region("small", "base")
        (base_x, base_y, _), _ = world.scene.pose("base")
        (small_x, small_y, _), _ = world.scene.pose("small")
        # The small block stands on the base where the base was moved to, not where it started.
        assert abs(small_x - base_x) < 0.03 and abs(small_y - base_y) < 0.03
        start = world.task.workspace.poses["pose20"].xy
        assert abs(base_x - start[0]) + abs(base_y - start[1]) > 0.05
    finally:
        world.close()


def test_a_failed_stacking_names_the_body_under_like_a_region() -> None:
    world = load_world(STACK, seed=0)
    try:
        skeleton = world.skeleton
        call = skeleton.transitions[3].calls[0]  # Inv-kin(small, #pose25, #dir2)
        graph = failure_graph(skeleton, 3, CheckResult(call, False, "no IK"))
    finally:
        world.close()
    labels = {node.id: node.label for node in graph.graph.nodes}
    edges = {(labels[e.source], labels[e.target], e.label) for e in graph.graph.edges}
    # The place decision takes the base as its region (arg1), and the base stands where the
    # earlier place decision put it.
    assert ("base", "#pose", "arg1") in edges
    assert ("#pose-1", "base", "at") in edges
    assert set(graph.bind.values()) == {"#pose13", "#dir2", "#pose25"}


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            '"On(small, base)"',
            '"On(small, small)"',
            "goal[1]: 'On(small, small)' names an unknown body or region",
        ),
        (
            '"Sample-pose(small, base) -> #pose25"',
            '"Sample-pose(small, small) -> #pose25"',
            "skeleton[6].decision: small cannot stand on itself",
        ),
    ],
)
def test_a_body_cannot_stand_on_itself(tmp_path: Path, old: str, new: str, message: str) -> None:
    text = STACK.read_text()
    assert old in text
    path = tmp_path / "self.yaml"
    path.write_text(text.replace(old, new))
    with pytest.raises(TaskError) as caught:
        load_task(str(path))
    assert str(caught.value) == f"{path}: {message}"

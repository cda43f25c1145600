"""A failed Inv-kin's graded `progress`: ordered by stage and closeness, and measured without
changing what IK draws (the seeded restarts, and so every method's verdicts, stay as they were)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from planner.sim import PyBulletWorld, load_world
from planner.sim.grasps import IkResult, make_grasp, solve_ik, tcp_target, total_penetration
from planner.sim.operators import (
    APPROACH_OUT_OF_REACH,
    IK_COLLIDES,
    IK_OUT_OF_REACH,
    Execution,
    first_guess,
    ik_progress,
)
from planner.skeleton import OperatorCall
from planner.world import PROGRESS_CAP

ON_OBSTACLE3 = [0.857, 0.929, 0.5]  # see tests/planner/sim/test_world.py


@pytest.fixture(scope="module")
def desk() -> Iterator[PyBulletWorld]:
    world = load_world("desk", seed=1)
    yield world
    world.close()


def missed(position_error: float = 0.1, least_depth: float = float("inf")) -> IkResult:
    return IkResult(None, position_error, 0.0, 8, 0, least_depth)


def test_progress_grows_with_closeness_and_stage() -> None:
    far, near = (
        ik_progress(IK_OUT_OF_REACH, [missed(0.3)]),
        ik_progress(IK_OUT_OF_REACH, [missed(0.01)]),
    )
    deep = ik_progress(IK_COLLIDES, [missed(least_depth=0.05)])
    shallow = ik_progress(IK_COLLIDES, [missed(least_depth=0.002)])
    approach = ik_progress(APPROACH_OUT_OF_REACH, [missed(0.3)])
    assert 0.0 <= far < near < deep < shallow < approach < PROGRESS_CAP
    # The closest of the tried grasps counts.
    assert ik_progress(IK_OUT_OF_REACH, [missed(0.3), missed(0.01)]) == near


def test_total_penetration_sums_the_deepest_per_body() -> None:
    assert total_penetration([("shelf", 0.01), ("shelf", 0.03), ("box", 0.02)]) == pytest.approx(
        0.05
    )
    assert total_penetration([]) == 0.0


def test_a_colliding_placement_reports_graded_progress(desk: PyBulletWorld) -> None:
    picked = desk.transition(0, {"#dir1": "front"}, desk.initial_state())
    assert picked.ok
    out = desk.transition(1, {"#dir1": "front", "#pose12": ON_OBSTACLE3}, picked.state)
    failed = out.failed
    assert failed is not None and failed.call.name == "Inv-kin"
    assert 0.0 < failed.detail["progress"] < PROGRESS_CAP
    if "least_depth" in failed.detail:  # reached, in collision
        assert failed.detail["progress"] >= IK_COLLIDES / 4


def test_measuring_draws_nothing_more(desk: PyBulletWorld) -> None:
    """Two solves of the same pose from one seed leave the generator in the same state as a
    generator that drew the same restarts: the bookkeeping takes no random numbers."""
    scene = desk.scene
    body_pose = scene.named_pose("pose0", "body")
    target = tcp_target(make_grasp(scene, "body", "top", body_pose), body_pose)
    far = ((1.6, 0.0, 0.3), target[1])
    rng = np.random.default_rng(7)
    result = solve_ik(scene, far, rng, restarts=5, iterations=50, tolerance=1e-3, first_guess=None)
    expected = np.random.default_rng(7)
    expected.uniform(
        np.asarray(scene.joint_low), np.asarray(scene.joint_high), (5, len(scene.joint_low))
    )
    assert result.q is None and result.least_depth == float("inf")
    assert rng.random() == expected.random()


def test_a_failed_ik_is_inconclusive(desk: PyBulletWorld) -> None:
    """IK's seeded restarts found no collision-free solution: not a proof, so the search may
    attempt the same bindings again."""
    picked = desk.transition(0, {"#dir1": "front"}, desk.initial_state())
    out = desk.transition(1, {"#dir1": "front", "#pose12": ON_OBSTACLE3}, picked.state)
    assert out.failed is not None and not out.conclusive


def test_a_randomised_check_draws_afresh_per_attempt_and_per_branch() -> None:
    call = OperatorCall("Inv-kin", ("body", "pose0", "#dir1"))

    def seed(bindings: dict, attempt: int = 0) -> int:
        ex = Execution(None, None, 5, bindings, {}, {}, (), None, attempt=attempt)  # type: ignore[arg-type]
        return ex.draw_seed(call, (0.1, 0.2, 0.3), "front")

    first = seed({"#dir1": "front"})
    assert seed({"#dir1": "front"}) == first  # a function of its inputs: reproducible
    assert seed({"#dir1": "front"}, attempt=1) != first
    assert seed({"#dir1": "front", "#pose12": [0.5, 0.5, 0.5]}) != first


def test_a_search_that_only_collides_runs_every_restart(desk: PyBulletWorld) -> None:
    """Restarts that reach the pose in collision are counted, with their least penetration,
    and the search runs all of them."""
    scene = desk.scene
    body_pose = scene.named_pose("pose0", "body")
    target = tcp_target(make_grasp(scene, "body", "top", body_pose), body_pose)

    def always_hits(q: tuple[float, ...]) -> list[tuple[str, float]]:
        return [("wall", 0.01)]

    found = solve_ik(
        scene,
        target,
        np.random.default_rng(3),
        restarts=8,
        iterations=100,
        tolerance=1e-3,
        first_guess=first_guess(scene, target),
        collisions=always_hits,
    )
    assert found.q is None and found.restarts == 8 and found.in_collision > 2
    assert found.least_depth == pytest.approx(0.01)

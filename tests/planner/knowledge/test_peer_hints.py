"""Other planners' feasible points as candidates of this planner's MPF maximisation."""

from __future__ import annotations

import pytest
from wait_support import wait_until

from client import CpkbClient
from contract.models import Constraint, LivePoint
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.knowledge.live import PeerHints
from planner.search.analytic import analytic_world


def _point(
    point_id: int, type_id: str, x: dict, feasible: bool = True, run: str = "a"
) -> LivePoint:
    return LivePoint(point_id=point_id, type_id=type_id, x=x, feasible=feasible, run=run)


def test_hints_map_each_point_through_the_binds_and_merge_each_run_whole_first() -> None:
    hints = PeerHints(per_type=2, limit=10)
    hints.add(_point(1, "grasp", {"#dir": "front"}))
    hints.add(_point(2, "place", {"#dir": "front", "#pose": [0.1, 0.2]}))
    hints.add(_point(3, "grasp", {"#dir": "top"}, feasible=False))  # a failure: no hint
    hints.add(_point(4, "place", {"#dir": "left", "#pose": [0.5, 0.5]}, run="b"))
    constraints = [
        Constraint(type_id="grasp", bind={"#dir": "#dir1"}),
        Constraint(type_id="place", bind={"#dir": "#dir1", "#pose": "#pose12"}),
    ]
    found, preferred = hints.for_request(constraints, {"#dir1", "#pose12"})
    assert found[:2] == [
        {"#dir1": "front", "#pose12": [0.1, 0.2]},  # run a passed both: its chain, preferred
        {"#dir1": "left", "#pose12": [0.5, 0.5]},  # run b, the newest, passed one of them
    ]
    assert preferred == len(found)
    assert {"#dir1": "front"} in found[2:]
    assert hints.used == len(found)
    # A fixed variable is not the hint's to give; a type the request does not bind gives none.
    fixed, preferred = hints.for_request(constraints[1:], {"#pose12"})
    assert fixed[:2] == [{"#pose12": [0.5, 0.5]}, {"#pose12": [0.1, 0.2]}] and preferred == 2
    assert {"#dir1": "front"} not in fixed
    other = [Constraint(type_id="other", bind={"#dir": "#dir1"})]
    assert hints.for_request(other, {"#dir1"}) == ([], 0)


def test_hints_keep_the_newest_per_type_and_at_most_the_limit() -> None:
    hints = PeerHints(per_type=2, limit=3)
    for i in range(5):
        hints.add(_point(i, "place", {"#pose": [i / 10]}, run=f"r{i}"))
    found, _ = hints.for_request([Constraint(type_id="place", bind={"#pose": "p"})], {"p"})
    assert found == [{"p": [0.4]}, {"p": [0.3]}]
    for i in range(5, 10):
        hints.add(_point(i, f"t{i}", {"#pose": [i / 10]}, run=f"r{i}"))
    many = [Constraint(type_id=f"t{i}", bind={"#pose": "p"}) for i in range(5, 10)]
    found, preferred = hints.for_request(many, {"p"})
    assert len(found) == 3 and preferred == 3  # every hint is preferred


def _place(session: KnowledgeSession, pose: list[float], rollout: int) -> bool:
    """The session's search grasps desk's body from the front and places it at `pose`."""
    bindings = {"#dir1": "front", "#pose12": pose}
    grasped = session.world.transition(0, bindings, None)
    session.on_transition(0, bindings, grasped, rollout=rollout)
    placed = session.world.transition(1, bindings, None)
    session.on_transition(1, bindings, placed, rollout=rollout)
    session.on_rollout_end(rollout)
    return placed.failed is None


def _poses(world, feasible: bool) -> list[float]:
    """A placement of desk's body, grasped from the front, that passes (or fails)."""
    for i in range(1000):
        pose = [((i * k * 0.6180339887) % 1.0) for k in (1, 2, 3)]
        placed = world.transition(1, {"#dir1": "front", "#pose12": pose}, None)
        if (placed.failed is None) == feasible:
            return pose
    raise AssertionError("no such placement")


def test_a_placement_another_planner_found_is_this_planners_next_suggestion(live_kb) -> None:
    world = analytic_world("desk")
    bad, good = _poses(world, feasible=False), _poses(world, feasible=True)
    config = KnowledgeConfig(live_points=True, refresh_rollouts=10**6, live_hints=4)
    without = KnowledgeConfig(live_points=True, live_hints=0)
    with CpkbClient(live_kb.url) as client:
        sessions = {
            hints: KnowledgeSession(
                client,
                live_kb.name,
                analytic_world("desk"),
                background=False,
                config=config if hints else without,
            )
            for hints in (True, False)
        }
        for session in sessions.values():
            session.prematch()
        a = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        a.prematch()
        assert not _place(a, bad, rollout=1)
        assert _place(a, good, rollout=2)
        a.close()

        answers = {}
        for hints, b in sessions.items():
            rollouts = iter(range(1, 10**6))
            wait_until(
                lambda b=b, rollouts=rollouts: (
                    b.on_rollout_end(next(rollouts)) or b.stats.live_points >= 2
                ),
                what="B taking in A's placements",
            )
            path = {"#dir1": "front"}
            constraints = b.constraints_at("#pose12", path)
            assert constraints
            place = b.skeleton.decisions[1]
            answers[hints] = b.suggest(place, path, [], constraints, seed=0, n=2)
            b.close()
            assert b.stats.kb_errors == 0
        assert answers[True].x["#pose12"] == pytest.approx(good)
        assert answers[False].x["#pose12"] != pytest.approx(good, abs=1e-3)
        assert sessions[True].stats.peer_hints > 0 and sessions[False].stats.peer_hints == 0

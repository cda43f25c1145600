"""Other planners' passed rollouts as whole bindings of this task (`PeerChains`)."""

from __future__ import annotations

from wait_support import wait_until

from client import CpkbClient
from client.models import LivePoint
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.knowledge.live import PeerChains
from planner.search.analytic import analytic_world

GRASP = {"grasp": [{"#dir": "#dir1"}]}
BINDS = {**GRASP, "place": [{"#dir": "#dir1", "#pose": "#pose12"}]}
VARIABLES = ["#dir1", "#pose12"]


def _point(pid: int, type_id: str, x: dict, rollout: int, ok: bool = True, run: str = "a"):
    return LivePoint(point_id=pid, type_id=type_id, x=x, feasible=ok, run=run, rollout=rollout)


def test_the_newest_whole_rollout_without_a_failure_once():
    chains = PeerChains()
    chains.add(_point(1, "grasp", {"#dir": "top"}, rollout=1))
    chains.add(_point(2, "place", {"#dir": "top", "#pose": [0.1]}, rollout=1))
    chains.add(_point(3, "grasp", {"#dir": "front"}, rollout=2))
    chains.add(_point(4, "place", {"#dir": "front", "#pose": [0.2]}, rollout=2, ok=False))
    chains.add(_point(5, "grasp", {"#dir": "left"}, rollout=3))  # gives no placement
    assert chains.next(BINDS, VARIABLES) == {"#dir1": "top", "#pose12": [0.1]}
    assert chains.next(BINDS, VARIABLES) is None and chains.followed == 1


def test_an_ambiguous_or_disagreeing_rollout_gives_none():
    chains = PeerChains()
    chains.add(_point(1, "grasp", {"#dir": "top"}, rollout=1))
    chains.add(_point(2, "place", {"#dir": "front", "#pose": [0.1]}, rollout=1))
    assert chains.next(BINDS, VARIABLES) is None  # the grasp disagrees
    chains.add(_point(3, "place", {"#dir": "top", "#pose": [0.1]}, rollout=2))
    twice = {"place": [*BINDS["place"], {"#dir": "#dir2", "#pose": "#pose22"}]}
    assert chains.next(twice, VARIABLES) is None  # a type bound twice maps ambiguously


def _place(session: KnowledgeSession, pose: list[float], rollout: int) -> bool:
    bindings = {"#dir1": "front", "#pose12": pose}
    for index in (0, 1):
        outcome = session.world.transition(index, bindings, None)
        session.on_transition(index, bindings, outcome, rollout=rollout)
    session.on_rollout_end(rollout)
    return outcome.failed is None


def test_a_binding_another_planner_passed_reaches_this_one_whole(live_kb) -> None:
    world = analytic_world("desk")
    poses = [[((i * k * 0.6180339887) % 1.0) for k in (1, 2, 3)] for i in range(1000)]
    outcomes = [world.transition(1, {"#dir1": "front", "#pose12": p}, None) for p in poses]
    bad = next(p for p, o in zip(poses, outcomes, strict=True) if o.failed is not None)
    good = next(p for p, o in zip(poses, outcomes, strict=True) if o.failed is None)
    config = KnowledgeConfig(live_points=True, follow_peers=True)
    with CpkbClient(live_kb.url) as client:
        a = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        b = KnowledgeSession(
            client, live_kb.name, analytic_world("desk"), background=False, config=config
        )
        a.prematch()
        b.prematch()
        b.on_rollout_end(1)  # the feed's cursor: from here on, A's points reach B
        assert not _place(a, bad, rollout=1)
        assert _place(a, good, rollout=2)
        a.close()
        rollouts = iter(range(2, 10**6))
        wait_until(
            lambda: b.on_rollout_end(next(rollouts)) or b.stats.live_points >= 2,
            what="B taking in A's points",
        )
        chain = b.next_chain()
        b.close()
    assert chain == {"#dir1": "front", "#pose12": good}
    assert b.stats.peer_chains == 1 and b.stats.errors == 0

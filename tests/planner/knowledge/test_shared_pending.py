"""Pending suggestions shared between planners that suggest in their own processes: another
planner's pending point pushes a local suggestion apart, through a real service."""

from __future__ import annotations

from client import CpkbClient
from contract.models import Constraint, PendingPoint
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.knowledge.local import in_request_terms
from planner.search.analytic import analytic_world

LIVE = KnowledgeConfig(live_points=True, live_pending=True, refresh_rollouts=10**6)
ALONE = KnowledgeConfig(live_points=True, refresh_rollouts=10**6)
BLOCKED = "back"  # desk's first grasp that fails at the start pose


def _session(client: CpkbClient, kb: str, config: KnowledgeConfig) -> KnowledgeSession:
    session = KnowledgeSession(client, kb, analytic_world("desk"), background=False, config=config)
    session.prematch()
    return session


def _first_grasp(session: KnowledgeSession, seed: int) -> str:
    grasp = session.skeleton.decisions[0]
    answer = session.suggest(grasp, {}, [], session.constraints_at("#dir1", {}), seed=seed)
    assert answer is not None and answer.method == "mpf-local"
    return str(answer.x["#dir1"])


def test_another_planners_pending_suggestion_pushes_a_local_one_apart(live_kb):
    with CpkbClient(live_kb.url) as client:
        maker = _session(client, live_kb.name, KnowledgeConfig())
        bindings = {"#dir1": BLOCKED}
        maker.on_transition(0, bindings, maker.world.transition(0, bindings, None), rollout=1)
        maker.on_rollout_end(1)
        maker.close()

        # Without the other's pending point, B's seed picks the grasp A was served.
        alone = _session(client, live_kb.name, ALONE)
        a = _session(client, live_kb.name, LIVE)
        chosen = _first_grasp(a, seed=3)
        assert _first_grasp(alone, seed=3) == chosen
        a.on_rollout_end(1)  # reports what it has pending: its grasp, no point answers it yet

        b = _session(client, live_kb.name, LIVE)
        b.on_rollout_end(1)  # B reports nothing yet and reads A's pending grasp back
        assert _first_grasp(b, seed=3) != chosen
        assert b.stats.pending_shared == 0  # counted when the run closes
        for session in (alone, a, b):
            session.close()
        assert b.stats.pending_shared >= 1
        assert all(s.stats.errors == 0 for s in (alone, a, b))

        # A closed: it withdrew its pending grasp, and a later planner is not pushed from it.
        c = _session(client, live_kb.name, LIVE)
        c.on_rollout_end(1)
        assert _first_grasp(c, seed=3) == chosen
        c.close()


def test_pending_points_of_another_task_map_through_the_types_labels():
    binds = [Constraint(type_id="t", bind={"#dir": "g2", "#pose": "p2"})]
    theirs = PendingPoint(x={"g2": "top", "p2": [0.1, 0.2, 0.3], "q": [0.5]}, binds=binds)
    mine = [
        Constraint(type_id="t", bind={"#dir": "grasp", "#pose": "place"}),
        Constraint(type_id="u", bind={"#pose": "place"}),
    ]
    shared = [(dict(theirs.x), (("t", (("#dir", "g2"), ("#pose", "p2"))),))]
    assert in_request_terms(shared, mine) == [{"grasp": "top", "place": [0.1, 0.2, 0.3]}]
    assert in_request_terms(shared, [Constraint(type_id="u", bind={"#pose": "place"})]) == []

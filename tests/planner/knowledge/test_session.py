"""The knowledge base in the loop, against a real service: points, labels, activation, transfer."""

from __future__ import annotations

import pytest

from client import CpkbClient
from planner.failures import failure_graph
from planner.knowledge import KnowledgeSession
from planner.run import run_plan
from planner.search import PWUCT
from planner.search.analytic import analytic_world, shelf_reachable
from planner.search.samplers.quasi_random import QuasiRandomSampler
from planner.tasks import build_skeleton, load_task
from planner.world import CheckResult, Culprit, TransitionOutcome, WorldGeometry


def blocked_grasp_type(client: CpkbClient, kb: str, task: str) -> str:
    world = analytic_world(task)
    outcome = world.transition(0, {"#dir1": "back"}, None)
    fg = failure_graph(world.skeleton, 0, outcome.failed)
    return client.match_types(kb, [fg.graph])[0].type_id


def test_the_blocked_grasp_type_is_stable_across_runs_and_tasks(live_kb):
    with CpkbClient(live_kb.url) as client:
        ids = {blocked_grasp_type(client, live_kb.name, "desk") for _ in range(2)}
        assert len(ids) == 1
        # deskP starts elsewhere (poseP): its blocked grasp is a different constraint...
        assert blocked_grasp_type(client, live_kb.name, "deskP") not in ids
        # ...while the shelf failure is one type in both tasks.
        shelf = []
        for task in ("deskP", "desk"):
            world = analytic_world(task)
            outcome = world.transition(1, {"#dir1": "top", "#pose12": [0.0, 1.0, 0.5]}, None)
            shelf.append(failure_graph(world.skeleton, 1, outcome.failed).graph)
        assert len({r.type_id for r in client.match_types(live_kb.name, shelf)}) == 1


def session_search(live_kb, task: str, seed: int, rollouts: int) -> KnowledgeSession:
    client = CpkbClient(live_kb.url)
    world = analytic_world(task)
    session = KnowledgeSession(client, live_kb.name, world, background=False)
    session.prematch()
    PWUCT(world, QuasiRandomSampler(), seed=seed, observer=session).run(
        rollouts, stop_at_first=False
    )
    session.close()
    return session


def test_every_evaluation_of_an_active_check_is_labelled(live_kb):
    session = session_search(live_kb, "desk", seed=0, rollouts=60)
    with CpkbClient(live_kb.url) as client:
        types = {t.type_id: t for t in client.list_types(live_kb.name)}
        assert sum(t.n_points for t in types.values()) == session.points_posted > 0
        shelf = next(t for t in types.values() if "shelf" in t.context)
        assert set(shelf.decisions) == {"#dir", "#pose"}
        # Placements that reached the shelf check and passed are feasible points of its type.
        assert 0 < shelf.n_infeasible < shelf.n_points
        points = list(client.iter_points(live_kb.name, shelf.type_id))
        for point in points:
            assert point.feasible == shelf_reachable(point.x["#pose"])
            assert point.source is not None and point.source["task"] == "desk"
    assert session.stats.types_activated == 0  # nothing existed before this run


def test_a_later_task_activates_the_types_before_any_failure(live_kb):
    first = session_search(live_kb, "deskP", seed=1, rollouts=30)
    world = analytic_world("desk")
    with CpkbClient(live_kb.url) as client:
        session = KnowledgeSession(client, live_kb.name, world)
        session.prematch()
        types = client.list_types(live_kb.name)
        assert sum(t.n_points for t in types) == first.points_posted
        # deskP's shelf type recurs in desk; its blocked grasp at poseP does not.
        shelf = [t for t in types if "shelf" in t.context]
        assert session.stats.types_activated == len(shelf) == 1
        assert session.stats.points_activated == shelf[0].n_points
        constraints = session.constraints_at("#pose12", {"#dir1": "front"})
        assert [set(c.bind.values()) for c in constraints] == [{"#dir1", "#pose12"}]
        # Looking ahead, the grasp is chosen jointly with a placement the shelf type allows.
        ahead = session.constraints_at("#dir1", {})
        assert [set(c.bind.values()) for c in ahead] == [{"#dir1", "#pose12"}]
        grasp = world.skeleton.decisions[0]
        answer = session.suggest(grasp, {}, ["front"], ahead, seed=0)
        assert answer is not None and set(answer.x) == {"#dir1", "#pose12"}
        assert answer.x["#dir1"] != "front"
        session.close()
        paper_rule = KnowledgeSession(client, live_kb.name, world, lookahead=False)
        paper_rule.prematch()
        assert paper_rule.constraints_at("#dir1", {}) == []
        paper_rule.close()


def test_run_plan_reports_what_the_knowledge_base_did(live_kb):
    common = {"kb_url": live_kb.url, "kb": live_kb.name}
    before = run_plan("analytic:deskP", "cp-bo", 3, max_rollouts=30, stop_at_first=False, **common)
    assert before.knowledge.points_posted > 0 and before.knowledge.types_activated == 0
    after = run_plan("analytic:desk", "cp-bo", 3, **common)
    assert after.solved
    assert after.knowledge.types_activated >= 1
    assert after.knowledge.points_activated >= before.knowledge.points_posted // 2
    report = after.to_json()
    for key in ("task", "method", "seed", "solved", "rollouts", "wall_s", "bindings", "kb_s"):
        assert key in report


@pytest.mark.slow
def test_an_unreachable_knowledge_base_is_a_clear_error():
    from client import ServiceUnavailable

    with pytest.raises(ServiceUnavailable):
        run_plan("analytic:desk", "cp-bo", 0, kb_url="http://127.0.0.1:9", max_rollouts=5)


class _PackSkeletonOnly:
    """The pack task's skeleton and name, without geometry: the session reads no more."""

    def __init__(self) -> None:
        self.name = "pack"
        self.skeleton = build_skeleton(load_task("pack"))
        self.geometry = WorldGeometry()


def pack_session(live_kb, client: CpkbClient, *, lookahead: bool) -> KnowledgeSession:
    """A session that met the three collisions between boxes in the tray."""
    world = _PackSkeletonOnly()
    session = KnowledgeSession(client, live_kb.name, world, background=False, lookahead=lookahead)
    for index, culprit in ((1, "body1"), (2, "body1"), (2, "body2")):
        place = world.skeleton.transitions[index].calls[3]  # Inv-kin at the tray
        failed = CheckResult(place, False, culprits=(Culprit(culprit, 0.01),))
        session.on_transition(index, PACK_BINDINGS, TransitionOutcome((failed,)), 1)
    session.on_rollout_end(1)
    return session


PACK_BINDINGS = {"#pose1": [0.5, 0.5, 0.5], "#pose2": [0.2, 0.2, 0.5], "#pose3": [0.8, 0.8, 0.5]}


def test_looking_ahead_takes_in_every_type_on_the_later_decisions(live_kb):
    """At the first box, the type between the second and the third box counts too: the first
    place must leave room for both of them side by side."""
    with CpkbClient(live_kb.url) as client:
        session = pack_session(live_kb, client, lookahead=True)
        ahead = session.constraints_at("#pose1", {})
        pairs = sorted(sorted(c.bind.values()) for c in ahead)
        assert pairs == [["#pose1", "#pose2"], ["#pose1", "#pose3"], ["#pose2", "#pose3"]]
        first = session.skeleton.decisions[0]
        answer = session.suggest(first, {}, [], ahead, seed=0)
        assert answer is not None and set(answer.x) == {"#pose1", "#pose2", "#pose3"}
        assert len(session.constraints_at("#pose2", {"#pose1": PACK_BINDINGS["#pose1"]})) == 3
        session.close()
        paper_rule = pack_session(live_kb, client, lookahead=False)
        assert paper_rule.constraints_at("#pose1", {}) == []
        at_third = paper_rule.constraints_at(
            "#pose3", {k: PACK_BINDINGS[k] for k in ("#pose1", "#pose2")}
        )
        assert len(at_third) == 2
        paper_rule.close()


def test_sessions_of_one_task_share_its_failure_graphs(live_kb):
    """A planner process plans one task many times: the second session of a task looks up
    the graphs the first one built (the same objects), another task builds its own."""
    with CpkbClient(live_kb.url) as client:
        first = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        first.prematch()
        again = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        other = KnowledgeSession(client, live_kb.name, analytic_world("deskP"), background=False)
        assert first.matcher._graphs and again.matcher._graphs is first.matcher._graphs
        assert other.matcher._graphs is not first.matcher._graphs
        again.prematch()
        other.prematch()
        shared = set(first.matcher._graphs) & set(other.matcher._graphs)
        assert shared and all(
            first.matcher._graphs[k] is not other.matcher._graphs[k] for k in shared
        )
        for session in (first, again, other):
            session.close()


class _CountingClient(CpkbClient):
    """The real client, counting the graphs it sends to `types/match`."""

    matched: list[int]

    def match_types(self, kb, graphs):  # type: ignore[no-untyped-def]
        self.matched.append(len(graphs))
        return super().match_types(kb, graphs)


def test_a_failure_prematch_found_absent_becomes_a_type_without_asking_again(live_kb):
    """Prematch learns the type ID of every graph the task could produce; a failure met later
    whose graph was absent then is activated with that ID and no second request, and its
    points are stored under it."""
    with _CountingClient(live_kb.url) as client:
        client.matched = []
        world = analytic_world("desk")
        session = KnowledgeSession(client, live_kb.name, world, background=False)
        session.prematch()
        assert len(client.matched) == 1 and session.stats.types_active == 0
        PWUCT(world, QuasiRandomSampler(), seed=0, observer=session).run(40, stop_at_first=False)
        session.close()
        assert len(client.matched) == 1
        assert session.stats.types_active > 0
        stored = {t.type_id for t in client.list_types(live_kb.name)}
        active = {a.type_id for a in session.active.values()}
        assert active == stored
        assert {
            client.match_types(live_kb.name, [a.failure.graph])[0].type_id
            for a in session.active.values()
        } == stored

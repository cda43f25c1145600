"""Live sharing: two knowledge sessions on one real service, B learning from A during its run."""

from __future__ import annotations

import dataclasses

import pytest
from wait_support import wait_until

from client import CpkbClient
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.search.analytic import analytic_world
from surrogate.encoding import SpaceEncoder

# No refetch of a held model during the test: what changes it is the live feed alone.
LIVE = KnowledgeConfig(live_points=True, refresh_rollouts=10**6)
BLOCKED = "back"  # desk's first grasp that fails at the start pose


def _grasp(session: KnowledgeSession, choice: str, rollout: int) -> None:
    """The session's search tries grasp `choice` in rollout `rollout` (and posts its point)."""
    bindings = {"#dir1": choice}
    outcome = session.world.transition(0, bindings, None)
    session.on_transition(0, bindings, outcome, rollout=rollout)
    session.on_rollout_end(rollout)


def _feasible_grasps(task: str = "desk") -> list[str]:
    world = analytic_world(task)
    choices = world.skeleton.decisions[0].domain.choices
    return [c for c in choices if world.transition(0, {"#dir1": c}, None).failed is None]


def _active_types(session: KnowledgeSession) -> set[str]:
    return {a.type_id for a in session.active.values()}


def test_a_planners_model_takes_in_another_planners_points_before_any_refit(live_kb):
    feasible = _feasible_grasps()
    assert len(feasible) >= 2
    with CpkbClient(live_kb.url) as client:
        a = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        a.prematch()
        _grasp(a, BLOCKED, rollout=1)
        (type_id,) = _active_types(a)

        b = KnowledgeSession(
            client, live_kb.name, analytic_world("desk"), background=False, config=LIVE
        )
        b.prematch()
        assert _active_types(b) == {type_id}
        grasp = b.skeleton.decisions[0]
        assert b.suggest(grasp, {}, [], b.constraints_at("#dir1", {}), seed=0) is not None
        held = b.guidance.local.model(type_id)
        fetches = b.guidance.local.fetches
        xs = [{"#dir": c} for c in feasible[:2]]
        z = SpaceEncoder(held.space).encode_points(xs)
        before = held.predictor.proba(z)

        for rollout, choice in enumerate(feasible[:2], start=2):
            _grasp(a, choice, rollout)
        assert b.guidance.local.model(type_id).predictor.proba(z) == pytest.approx(before)
        b.on_rollout_end(1)

        after = b.guidance.local.model(type_id)
        assert after.version == held.version and b.guidance.local.fetches == fetches
        assert b.stats.live_points == 2 and after.n_points == held.n_points + 2
        # Two feasible points where the model held none: P(feasible) rises there.
        assert all(after.predictor.proba(z) > before + 0.1)
        for session in (a, b):
            session.close()
        assert b.stats.kb_errors == 0


def test_the_own_points_of_a_planner_do_not_come_back_to_it(live_kb):
    feasible = _feasible_grasps()
    with CpkbClient(live_kb.url) as client:
        b = KnowledgeSession(
            client, live_kb.name, analytic_world("desk"), background=False, config=LIVE
        )
        b.prematch()
        for rollout, choice in enumerate([BLOCKED, *feasible[:2]], start=1):
            _grasp(b, choice, rollout)
        b.on_rollout_end(4)
        b.close()
        assert b.points_posted == 3 and b.stats.live_points == 0 and b.stats.kb_errors == 0


@pytest.mark.parametrize("background", [False, True])
def test_a_type_another_planner_creates_becomes_active_at_once(live_kb, background):
    with CpkbClient(live_kb.url) as client:
        b = KnowledgeSession(
            client, live_kb.name, analytic_world("desk"), background=background, config=LIVE
        )
        b.prematch()
        assert b.stats.types_active == 0 and b.matcher._absent

        a = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        a.prematch()
        _grasp(a, BLOCKED, rollout=1)
        (type_id,) = _active_types(a)

        rollouts = iter(range(1, 10**6))
        wait_until(
            lambda: b.on_rollout_end(next(rollouts)) or type_id in _active_types(b),
            what="B activating the type A created",
        )
        assert b.stats.live_types == 1 and b.stats.types_active == 1
        constraints = b.constraints_at("#dir1", {})
        assert [c.type_id for c in constraints] == [type_id]
        grasp = b.skeleton.decisions[0]
        assert b.suggest(grasp, {}, [], constraints, seed=0) is not None
        model = b.guidance.local.model(type_id)
        blocked = SpaceEncoder(model.space).encode_points([{"#dir": BLOCKED}])
        assert model.predictor.proba(blocked)[0] < 0.5  # A's failure there, in B's model
        for session in (a, b):
            session.close()
        assert b.stats.kb_errors == 0


def test_a_planner_that_polls_for_nothing_polls_less_until_points_come(live_kb):
    """`knowledge.live_idle_max`: empty answers space the polls out; A's point restores the pace."""
    feasible = _feasible_grasps()
    with CpkbClient(live_kb.url) as client:
        a = KnowledgeSession(client, live_kb.name, analytic_world("desk"), background=False)
        a.prematch()
        _grasp(a, BLOCKED, rollout=1)
        sessions = {
            idle_max: KnowledgeSession(
                client,
                live_kb.name,
                analytic_world("desk"),
                background=False,
                config=dataclasses.replace(LIVE, live_idle_max=idle_max),
            )
            for idle_max in (1, 8)
        }
        for session in sessions.values():
            session.prematch()
        polls = {idle_max: s.sharing.live.polls for idle_max, s in sessions.items()}
        for rollout in range(1, 41):
            for session in sessions.values():
                session.on_rollout_end(rollout)
        assert sessions[1].sharing.live.polls - polls[1] == 40
        assert (
            sessions[8].sharing.live.polls - polls[8] <= 8
            and sessions[8].sharing.live.schedule.gap == 8
        )
        # The found-bindings poll of the task follows the same rule.
        assert (
            sessions[1].guidance.found.schedule.gap == 1
            and sessions[8].guidance.found.schedule.gap == 8
        )

        _grasp(a, feasible[0], rollout=2)
        for rollout in range(41, 50):
            sessions[8].on_rollout_end(rollout)
        assert sessions[8].stats.live_points == 1 and sessions[8].sharing.live.schedule.gap <= 2
        for session in (a, *sessions.values()):
            session.close()
            assert session.stats.kb_errors == 0

"""The knowledge client's contract (`planner.knowledge.client.KnowledgeClient`), one suite run
over the in-memory implementation and over `CpkbClient` against a real service on loopback, as
Optuna's storage tests run over every storage."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from typing import Any

import pytest

from client import CpkbClient
from client.errors import NotFound
from contract.bindings import BindingIn
from contract.models import Constraint, PointIn, Source, SuggestIn
from planner.failures import FailureGraph, failure_graph
from planner.knowledge import KnowledgeClient, KnowledgeSession
from planner.knowledge.memory import InMemoryKnowledge
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers.cp_bo import CpBoSampler


@pytest.fixture(params=["memory", "http"])
def knowledge(request: pytest.FixtureRequest) -> Iterator[tuple[Any, str]]:
    kb = f"c-{uuid.uuid4().hex[:12]}"
    if request.param == "memory":
        memory = InMemoryKnowledge()
        memory.create_kb(kb)
        yield memory, kb
        return
    with CpkbClient(request.getfixturevalue("kb_service")) as client:
        client.create_kb(kb)
        yield client, kb


def _failures() -> tuple[FailureGraph, FailureGraph]:
    """The desk's blocked grasp, and its shelf placement that failed (two types)."""
    world = analytic_world("desk")
    grasp = world.transition(0, {"#dir1": "back"}, None).failed
    place = world.transition(1, {"#dir1": "top", "#pose12": [0.0, 1.0, 0.5]}, None).failed
    assert grasp is not None and place is not None
    return failure_graph(world.skeleton, 0, grasp), failure_graph(world.skeleton, 1, place)


def _point(fg: FailureGraph, x: dict, feasible: bool, run: str, key: str) -> PointIn:
    return PointIn(
        graph=fg.graph,
        x=x,
        feasible=feasible,
        source=Source(task="desk", run=run, rollout=1),
        key=key,
    )


def _place_x(i: int) -> dict:
    return {"#dir": "top", "#pose": [0.1 * i, 0.5, 0.5]}


def test_both_implement_the_protocol(knowledge: tuple[Any, str]) -> None:
    client, _ = knowledge
    for name in KnowledgeClient.__dict__:
        if not name.startswith("_"):
            assert callable(getattr(client, name))


def test_a_graph_is_one_type_matched_before_and_after_its_points(knowledge) -> None:
    client, kb = knowledge
    grasp, place = _failures()
    before = client.match_types(kb, [place.graph])[0]
    assert not before.exists and before.n_points == 0
    x = {label: _place_x(1)[label] for label in place.bind}
    results = client.post_points(kb, [_point(place, x, False, "r1", "k1")])
    assert results[0].type_id == before.type_id and results[0].new_type
    client.post_points(kb, [_point(place, x, False, "r1", "k1")])  # a retry stores nothing
    after, other = client.match_types(kb, [place.graph, grasp.graph])
    assert after.type_id == before.type_id and after.exists and after.n_points == 1
    assert other.type_id != after.type_id and not other.exists
    detail = client.get_type(kb, after.type_id)
    assert detail.n_points == 1 and detail.n_infeasible == 1
    assert set(detail.decisions) == set(place.bind) and set(detail.space) == set(place.bind)
    assert detail.surrogate is not None


def test_points_since_a_cursor_leave_out_the_callers_run(knowledge) -> None:
    client, kb = knowledge
    _, place = _failures()
    start = client.points_since(kb, [], None)
    assert start.points == []
    type_id = client.match_types(kb, [place.graph])[0].type_id
    for i, run in enumerate(["mine", "theirs", "theirs"]):
        x = {label: _place_x(i)[label] for label in place.bind}
        client.post_points(kb, [_point(place, x, i == 2, run, f"p{i}")])
    answer = client.points_since(kb, [type_id, "unknown"], start.cursor, exclude_run="mine")
    assert [(p.run, p.feasible) for p in answer.points] == [("theirs", False), ("theirs", True)]
    assert all(p.type_id == type_id for p in answer.points) and not answer.more
    assert client.points_since(kb, [type_id], answer.cursor).points == []


def test_models_are_sent_unless_their_version_is_known(knowledge) -> None:
    client, kb = knowledge
    _, place = _failures()
    x = {label: _place_x(3)[label] for label in place.bind}
    type_id = client.post_points(kb, [_point(place, x, False, "r", "m")])[0].type_id
    first = client.models(kb, [type_id])
    assert [m.type_id for m in first.models] == [type_id] and first.optimizer
    version = first.models[0].version
    assert client.models(kb, [type_id], {type_id: version}).models == []


def test_a_suggestion_lies_in_the_space_and_avoids_what_is_excluded(knowledge) -> None:
    client, kb = knowledge
    _, place = _failures()
    x = {label: _place_x(2)[label] for label in place.bind}
    type_id = client.post_points(kb, [_point(place, x, False, "r", "s")])[0].type_id
    space = {var: label for label, var in place.bind.items()}
    domains = {v.var: v.domain for v in analytic_world("desk").skeleton.decisions}
    request = SuggestIn(
        space={var: domains[var] for var in space},
        constraints=[Constraint(type_id=type_id, bind=dict(place.bind))],
        exclude=[{"#dir1": "top"}],
        seed=1,
    )
    answer = client.suggest(kb, request)
    assert answer.x["#dir1"] != "top" and len(answer.x["#pose12"]) == 3
    assert 0.0 <= answer.mpf <= 1.0
    unknown = Constraint(type_id="0" * 32, bind=dict(place.bind))
    with pytest.raises(NotFound):
        client.suggest(kb, request.model_copy(update={"constraints": [unknown]}))


def test_found_bindings_by_task_and_skeleton_after_a_cursor(knowledge) -> None:
    client, kb = knowledge

    def binding(task: str, run: str, skeleton: str = "s1") -> BindingIn:
        return BindingIn(task=task, skeleton=skeleton, run=run, rollout=3, bindings={"#d": "a"})

    first = client.add_binding(kb, binding("desk", "a"))
    client.add_binding(kb, binding("desk", "b"))
    client.add_binding(kb, binding("pack", "a"))
    client.add_binding(kb, binding("desk", "a", skeleton="s2"))
    page = client.bindings(kb, skeleton="s1", task="desk", exclude_run="b")
    assert [b.binding_id for b in page.bindings] == [first.binding_id]
    later = client.bindings(kb, skeleton="s1", task="desk", after=page.cursor)
    assert later.bindings == [] and later.cursor >= page.cursor


def test_an_unknown_knowledge_base_is_not_found(knowledge) -> None:
    client, _ = knowledge
    with pytest.raises(NotFound):
        client.match_types(f"none-{uuid.uuid4().hex[:8]}", [_failures()[0].graph])


def test_a_cp_bo_search_runs_on_either(knowledge) -> None:
    """A whole guided search in the foreground: the session needs nothing beyond the
    contract."""
    client, kb = knowledge
    world = analytic_world("desk")
    session = KnowledgeSession(client, kb, world, background=False)
    session.prematch()
    outcome = PWUCT(world, CpBoSampler(session), seed=0, observer=session).run(300)
    session.close()
    assert outcome.solved and session.stats.kb_errors == 0, session.stats.events
    assert session.stats.suggestions > 0 and session.points_posted > 0

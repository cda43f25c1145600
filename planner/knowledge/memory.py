"""A knowledge base in this process: the `KnowledgeClient` contract without a service.

For tests and experiments that need the planner's side of the knowledge base but no server: types
are keyed by their graph as the planner builds it (its vertex IDs are already task-independent),
points are fitted by `surrogate.sources.InMemoryModels` as the service fits them, suggestions and
model snapshots come from the same code the service runs (`surrogate.suggest`, `fetch_from`).
`tests/planner/knowledge/test_client_contract.py` holds it to the same contract as `CpkbClient`
against a real service.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from client.errors import BadRequest, Conflict, NotFound
from contract.bindings import BindingIn, BindingOut, BindingsPage
from contract.models import (
    MAX_POINTS_PER_POST,
    Graph,
    LivePoint,
    MatchResult,
    ModelsOut,
    PointIn,
    PointResult,
    PointsSinceOut,
    SuggestIn,
    SuggestOut,
    SurrogateState,
    TypeDetail,
)
from planner.knowledge.local import fetch_from
from surrogate.config import SurrogateConfig
from surrogate.domains import space_from_json
from surrogate.optimize import OptimizerConfig, SpaceExhausted
from surrogate.pending import PendingBook
from surrogate.sources import InMemoryModels
from surrogate.suggest import InvalidRequest, SuggestRequest
from surrogate.suggest import suggest as suggest_point


def graph_key(graph: Graph) -> str:
    """A type's ID: a digest of its graph, vertexes and edges in a fixed order."""
    nodes = sorted(json.dumps(n.model_dump(mode="json"), sort_keys=True) for n in graph.nodes)
    edges = sorted(json.dumps(e.model_dump(mode="json"), sort_keys=True) for e in graph.edges)
    canonical = json.dumps([nodes, edges])
    return hashlib.sha256(canonical.encode()).hexdigest()[:32]


@dataclass
class _Point:
    point_id: int
    type_id: str
    x: dict
    feasible: bool
    run: str | None
    rollout: int | None


@dataclass
class _Kb:
    graphs: dict[str, Graph] = field(default_factory=dict)
    points: list[_Point] = field(default_factory=list)
    keys: dict[str, PointResult] = field(default_factory=dict)
    models: InMemoryModels = field(default_factory=InMemoryModels)
    pending: PendingBook = field(
        default_factory=lambda: PendingBook(SurrogateConfig().pending_ttl_s)
    )
    bindings: list[BindingOut] = field(default_factory=list)


class InMemoryKnowledge:
    def __init__(self, optimizer: OptimizerConfig | None = None) -> None:
        self._optimizer = optimizer if optimizer is not None else OptimizerConfig()
        self._kbs: dict[str, _Kb] = {}
        self._ids = itertools.count(1)  # point and binding IDs, one sequence for every base
        self._top = 0

    def create_kb(self, name: str, *, exist_ok: bool = False) -> None:
        if name in self._kbs and not exist_ok:
            raise Conflict(f"knowledge base {name!r} exists", status=409)
        self._kbs.setdefault(name, _Kb())

    def post_points(self, kb: str, points: Sequence[PointIn]) -> list[PointResult]:
        base = self._kb(kb)
        if len(points) > MAX_POINTS_PER_POST:
            raise BadRequest(f"at most {MAX_POINTS_PER_POST} points per post", status=422)
        results = []
        for point in points:
            if point.key is not None and point.key in base.keys:
                results.append(base.keys[point.key])
                continue
            type_id = graph_key(point.graph)
            new = type_id not in base.graphs
            space = _space(point.graph)
            if set(point.x) != set(space):
                raise BadRequest(f"x must give exactly {sorted(space)}", status=422)
            base.graphs.setdefault(type_id, point.graph)
            self._top = next(self._ids)
            source = point.source
            base.points.append(
                _Point(
                    self._top,
                    type_id,
                    dict(point.x),
                    point.feasible,
                    source.run if source is not None else None,
                    source.rollout if source is not None else None,
                )
            )
            base.models.add(type_id, space_from_json(_json(space)), [(point.x, point.feasible)])
            base.pending.answered(kb, type_id, [point.x])
            result = PointResult(type_id=type_id, point_id=self._top, new_type=new)
            if point.key is not None:
                base.keys[point.key] = result
            results.append(result)
        return results

    def match_types(self, kb: str, graphs: Sequence[Graph]) -> list[MatchResult]:
        base = self._kb(kb)
        out = []
        for graph in graphs:
            type_id = graph_key(graph)
            n = sum(p.type_id == type_id for p in base.points)
            out.append(MatchResult(type_id=type_id, exists=type_id in base.graphs, n_points=n))
        return out

    def suggest(self, kb: str, request: SuggestIn) -> SuggestOut:
        base = self._kb(kb)
        for constraint in request.constraints:
            self._type(base, constraint.type_id)
        try:
            answer = suggest_point(
                base.models,
                SuggestRequest.from_json(request.model_dump()),
                base.pending,
                key=kb,
                config=self._optimizer,
            )
        except InvalidRequest as exc:
            raise BadRequest(str(exc), status=422) from None
        except SpaceExhausted as exc:
            raise Conflict(f"exclude: {exc}", status=409) from None
        return SuggestOut.model_validate(answer.to_json())

    def models(
        self, kb: str, type_ids: Sequence[str], known: dict[str, str] | None = None
    ) -> ModelsOut:
        base = self._kb(kb)
        for type_id in type_ids:
            self._type(base, type_id)
        fetch = fetch_from(base.models, self._optimizer, base.pending.ttl_s)
        return fetch(list(type_ids), dict(known or {}))

    def get_type(self, kb: str, type_id: str) -> TypeDetail:
        base = self._kb(kb)
        graph = self._type(base, type_id)
        points = [p for p in base.points if p.type_id == type_id]
        labels = {role: [n.label for n in graph.nodes if n.role == role] for role in _ROLES}
        return TypeDetail(
            type_id=type_id,
            failure=labels["failure"][0],
            decisions=labels["decision"],
            context=labels["context"],
            n_points=len(points),
            n_infeasible=sum(not p.feasible for p in points),
            graph=graph,
            space=_space(graph),
            # Fitted when a model is asked for: every point is in the model the next request gets.
            surrogate=SurrogateState(status="ready", n_fitted=len(points)),
        )

    def points_since(
        self,
        kb: str,
        type_ids: Iterable[str],
        after_point_id: int | None = None,
        *,
        exclude_run: str | None = None,
        limit: int = MAX_POINTS_PER_POST,
    ) -> PointsSinceOut:
        base = self._kb(kb)
        watched = set(type_ids)
        if after_point_id is None or not watched:
            return PointsSinceOut(points=[], cursor=max(self._top, after_point_id or 0))
        rows = [
            p
            for p in base.points
            if p.type_id in watched
            and p.point_id > after_point_id
            and (exclude_run is None or p.run != exclude_run)
        ]
        more = len(rows) > limit
        rows = rows[:limit]
        cursor = rows[-1].point_id if more else max(self._top, after_point_id)
        points = [
            LivePoint(
                point_id=p.point_id,
                type_id=p.type_id,
                x=p.x,
                feasible=p.feasible,
                run=p.run,
                rollout=p.rollout,
            )
            for p in rows
        ]
        return PointsSinceOut(points=points, cursor=cursor, more=more)

    def add_binding(self, kb: str, binding: BindingIn) -> BindingOut:
        base = self._kb(kb)
        stored = BindingOut(binding_id=next(self._ids), **binding.model_dump())
        base.bindings.append(stored)
        return stored

    def bindings(
        self,
        kb: str,
        *,
        skeleton: str | None = None,
        task: str | None = None,
        after: int | None = None,
        exclude_run: str | None = None,
    ) -> BindingsPage:
        base = self._kb(kb)
        rows = [
            b
            for b in base.bindings
            if (skeleton is None or b.skeleton == skeleton)
            and (task is None or b.task == task)
            and (after is None or b.binding_id > after)
            and (exclude_run is None or b.run != exclude_run)
        ]
        top = max((b.binding_id for b in base.bindings), default=0)
        return BindingsPage(bindings=rows, cursor=max(top, after or 0))

    def _kb(self, kb: str) -> _Kb:
        if kb not in self._kbs:
            raise NotFound(f"no knowledge base {kb!r}", status=404)
        return self._kbs[kb]

    def _type(self, base: _Kb, type_id: str) -> Graph:
        if type_id not in base.graphs:
            raise NotFound(f"no type {type_id!r}", status=404)
        return base.graphs[type_id]


_ROLES = ("failure", "decision", "context")


def _space(graph: Graph) -> dict:
    return {n.label: n.domain for n in graph.nodes if n.role == "decision"}


def _json(space: dict) -> dict:
    return {label: domain.model_dump() for label, domain in space.items()}

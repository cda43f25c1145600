"""CP types: match graphs, list, detail, and a type's points loaded for fitting."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from pydantic import TypeAdapter
from sqlalchemy import select
from sqlalchemy.orm import Session

from contract.models import Domain, Graph, MatchResult, TypeDetail, TypeSummary, Value
from server.db import Store
from server.errors import Conflict, InvalidInput, NotFound, TooLarge
from server.graphs import GraphError, ResolvedGraph, TypeConflict, check_same_type, resolve_graph
from server.orm import PointRow, TypeRow
from server.services.kbs import kb_id

_space_adapter: TypeAdapter[dict[str, Domain]] = TypeAdapter(dict[str, Domain])


def check_graph_work(graphs: Iterable[Graph], max_nodes: int) -> None:
    """413 when the distinct graphs of a request hold more than `max_nodes` nodes in all: the
    work of hashing them is what a request may not ask for without bound."""
    distinct = {graph.model_dump_json(): len(graph.nodes) for graph in graphs}
    total = sum(distinct.values())
    if total > max_nodes:
        raise TooLarge(
            f"the request's {len(distinct)} distinct graphs hold {total} nodes; one request "
            f"may hold {max_nodes} (CPKB_MAX_REQUEST_GRAPH_NODES): send fewer graphs per request"
        )


def resolve_or_422(graph: Graph, where: str) -> ResolvedGraph:
    try:
        return resolve_graph(graph)
    except GraphError as exc:
        raise InvalidInput(f"{where}.{exc}") from exc


def check_or_409(resolved: ResolvedGraph, stored_graph: dict[str, Any]) -> None:
    try:
        check_same_type(resolved, stored_graph)
    except TypeConflict as exc:
        raise Conflict(str(exc)) from exc


def type_row(session: Session, kb: str, type_id: str) -> TypeRow:
    row = session.scalar(
        select(TypeRow).where(TypeRow.kb_id == kb_id(session, kb), TypeRow.type_id == type_id)
    )
    if row is None:
        raise NotFound(f"type {type_id!r} not found in knowledge base {kb!r}")
    return row


def summary(row: TypeRow) -> TypeSummary:
    return TypeSummary(
        type_id=row.type_id,
        failure=row.failure,
        decisions=list(row.decisions),
        context=list(row.context),
        n_points=row.n_points,
        n_infeasible=row.n_infeasible,
        created_at=row.created_at,
        updated_at=row.updated_at,
    )


def match_types(store: Store, kb: str, graphs: list[Graph], *, max_nodes: int) -> list[MatchResult]:
    """For each graph its type ID and whether the knowledge base has it (409 on a conflict;
    413 for graphs of more than `max_nodes` nodes in all)."""
    check_graph_work(graphs, max_nodes)
    resolved = [resolve_or_422(g, f"graphs[{i}]") for i, g in enumerate(graphs)]
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
        ids = {r.type_id for r in resolved}
        rows = {
            row.type_id: row
            for row in session.scalars(
                select(TypeRow).where(TypeRow.kb_id == kb_pk, TypeRow.type_id.in_(ids))
            )
        }
        results = []
        for r in resolved:
            row = rows.get(r.type_id)
            if row is not None:
                check_or_409(r, row.graph)
            results.append(
                MatchResult(
                    type_id=r.type_id, exists=row is not None, n_points=row.n_points if row else 0
                )
            )
        return results


def list_types(store: Store, kb: str) -> list[TypeSummary]:
    """The types of a knowledge base, most recently updated first."""
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
        rows = session.scalars(
            select(TypeRow)
            .where(TypeRow.kb_id == kb_pk)
            .order_by(TypeRow.updated_at.desc(), TypeRow.type_id)
        )
        return [summary(row) for row in rows]


def get_type(store: Store, kb: str, type_id: str) -> TypeDetail:
    """The type with its canonical graph and decision space (surrogate state added by the API)."""
    with store.transaction() as session:
        row = type_row(session, kb, type_id)
        return TypeDetail(
            **summary(row).model_dump(),
            graph=Graph.model_validate(row.graph),
            space=_space_adapter.validate_python(row.space),
        )


@dataclass(frozen=True)
class TrainingPoints:
    """A type's points in id order, as a surrogate fit wants them.

    `x[i]` is `{decision label: value}`, `feasible[i]` its label; `version` is the type's point
    count when read (it only grows; on PostgreSQL `x` may already hold a few points more),
    `last_point_id` the cursor to pass as `after_point_id` next time. `origin` names the type's
    row (id and creation time): a type deleted with its knowledge base and created again has
    another, though SQLite may give it the same ids.
    """

    type_id: str
    space: dict[str, Domain]
    x: list[dict[str, Value]]
    feasible: list[bool]
    version: int
    last_point_id: int | None
    origin: tuple[int, datetime]


def load_training_points(
    store: Store, kb: str, type_id: str, *, after_point_id: int | None = None
) -> TrainingPoints:
    """All points of a type (or those after `after_point_id`), two columns only: fast."""
    with store.transaction() as session:
        row = type_row(session, kb, type_id)
        query = select(PointRow.id, PointRow.x, PointRow.feasible).where(PointRow.type_pk == row.id)
        if after_point_id is not None:
            query = query.where(PointRow.id > after_point_id)
        points = session.execute(query.order_by(PointRow.id)).all()
        return TrainingPoints(
            type_id=type_id,
            space=_space_adapter.validate_python(row.space),
            x=[p.x for p in points],
            feasible=[bool(p.feasible) for p in points],
            version=row.n_points,
            last_point_id=points[-1].id if points else after_point_id,
            origin=(row.id, row.created_at),
        )

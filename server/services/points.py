"""Posting points (bulk, idempotent), paging through a type's points, CSV export.

A post is validated and hashed before any transaction starts; the write transaction then
inserts new types and points with `ON CONFLICT DO NOTHING`, so that a repeated idempotency key,
even one racing in from another process, stores nothing and gets the original answer.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Any, cast

from sqlalchemy import ColumnElement, Select, Table, bindparam, func, insert, or_, select, update
from sqlalchemy.orm import Session

from contract.models import (
    MAX_SOURCE_DEPTH,
    LivePoint,
    PointIn,
    PointOut,
    PointResult,
    PointsPage,
    PointsSinceIn,
    PointsSinceOut,
)
from server.db import Store
from server.errors import Conflict, InvalidInput
from server.graphs import GraphError, ResolvedGraph, check_x
from server.orm import PointRow, TypeRow, utcnow
from server.services.kbs import kb_id
from server.services.types import check_graph_work, check_or_409, resolve_or_422, type_row
from server.settings import DEFAULT_GRAPH_NODES
from server.sql import insert_ignoring_conflicts

INT64 = 2**63 - 1
PROVENANCE = ("task", "run", "rollout", "worker", "time")


@dataclass(frozen=True)
class PostOutcome:
    results: list[PointResult]
    # Types that gained at least one point in this post (for the surrogate engine).
    touched: frozenset[str]
    n_new: int
    n_new_types: int


def _finite_json(value: Any, where: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise InvalidInput(f"{where}: {value} is not a finite number")
    if isinstance(value, dict):
        for k, v in value.items():
            _finite_json(v, f"{where}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _finite_json(v, f"{where}[{i}]")


def _row(point: PointIn, where: str) -> dict[str, Any]:
    """The column values of a point (without kb and type), provenance checked."""
    source = point.source.model_dump() if point.source is not None else {}
    extra = {k: v for k, v in source.items() if k not in PROVENANCE}
    _finite_json(extra, f"{where}.source")
    rollout = source.get("rollout")
    if rollout is not None and not -INT64 <= rollout <= INT64:
        raise InvalidInput(f"{where}.source.rollout: {rollout} does not fit in 64 bits")
    return {
        "x": point.x,
        "feasible": point.feasible,
        "task": source.get("task"),
        "run": source.get("run"),
        "rollout": rollout,
        "worker": source.get("worker"),
        "time": source.get("time"),
        "extra": extra or None,
        "key": point.key,
    }


def _prepare(points: list[PointIn]) -> tuple[list[ResolvedGraph], list[dict[str, Any]]]:
    resolved, rows = [], []
    for i, point in enumerate(points):
        where = f"points[{i}]"
        graph = resolve_or_422(point.graph, f"{where}.graph")
        try:
            check_x(point.x, graph.space)
        except GraphError as exc:
            raise InvalidInput(f"{where}.{exc}") from exc
        resolved.append(graph)
        row = _row(point, where)
        row["payload_hash"] = _payload_hash(graph.type_id, row) if point.key else None
        rows.append(row)
    return resolved, rows


def _payload_hash(type_id: str, row: dict[str, Any]) -> str:
    """What an idempotency key stands for: the point's type, value, label and provenance."""
    content = {name: row[name] for name in ("x", "feasible", *PROVENANCE, "extra")}
    text = json.dumps([type_id, content], sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _check_same_payload(key: str, stored: str | None, posted: str | None) -> None:
    """A key names one request: a different point under it is refused. Points stored before
    the hash was kept (None) replay for any payload."""
    if stored is not None and stored != posted:
        raise Conflict(
            f"idempotency key {key!a} was already used for a different point: "
            "send a new key for a new point"
        )


_TYPES = cast(Table, TypeRow.__table__)
_POINTS = cast(Table, PointRow.__table__)
_TYPE_COLUMNS = (_TYPES.c.id, _TYPES.c.type_id, _TYPES.c.graph)
_COUNT = (
    update(_TYPES)
    .where(_TYPES.c.id == bindparam("pk"))
    .values(
        n_points=_TYPES.c.n_points + bindparam("n"),
        n_infeasible=_TYPES.c.n_infeasible + bindparam("n_infeasible"),
        updated_at=bindparam("now"),
    )
)


def _stored_types(session: Session, kb_pk: int, type_ids: Iterable[str]) -> dict[str, Any]:
    query = select(*_TYPE_COLUMNS).where(
        _TYPES.c.kb_id == kb_pk, _TYPES.c.type_id.in_(list(type_ids))
    )
    return {row.type_id: row for row in session.execute(query)}


def _types(
    session: Session, kb_pk: int, resolved: list[ResolvedGraph]
) -> dict[str, tuple[int, bool]]:
    """type_id -> (row id, created by this post); new types inserted, stored ones checked."""
    distinct = {r.type_id: r for r in resolved}
    stored = _stored_types(session, kb_pk, distinct)
    created: set[str] = set()
    missing = sorted(set(distinct) - set(stored))
    if missing:
        now = utcnow()
        fresh = [
            {
                "kb_id": kb_pk,
                "type_id": r.type_id,
                "failure": r.failure,
                "decisions": r.decisions,
                "context": r.context,
                "graph": r.canonical,
                "space": r.space_json(),
                "n_points": 0,
                "n_infeasible": 0,
                "created_at": now,
                "updated_at": now,
            }
            for r in (distinct[t] for t in missing)
        ]
        # Another writer may create the same type meanwhile: its row wins, ours is skipped.
        stmt = insert_ignoring_conflicts(session, _TYPES, ["kb_id", "type_id"])
        created = {t for (t,) in session.execute(stmt.returning(_TYPES.c.type_id), fresh)}
        stored.update(_stored_types(session, kb_pk, missing))
    checked: set[int] = set()
    for r in resolved:
        if id(r) not in checked:
            check_or_409(r, stored[r.type_id].graph)
            checked.add(id(r))
    return {t: (row.id, t in created) for t, row in stored.items()}


def add_points(
    store: Store, kb: str, points: list[PointIn], *, max_nodes: int = DEFAULT_GRAPH_NODES
) -> PostOutcome:
    """Store a batch in one transaction; a repeated key gets its original result. 413 when
    the batch's distinct graphs hold more than `max_nodes` nodes in all."""
    check_graph_work((p.graph for p in points), max_nodes)
    resolved, rows = _prepare(points)
    with store.transaction(write=True) as session:
        kb_pk = kb_id(session, kb)
        types = _types(session, kb_pk, resolved)
        _lock_types(session, [pk for pk, _ in types.values()])
        now = utcnow()
        announced: set[str] = set()
        for graph, row in zip(resolved, rows, strict=True):
            type_pk, created = types[graph.type_id]
            # Only the first point of a type this post created says so.
            new_type = created and graph.type_id not in announced
            announced.add(graph.type_id)
            row.update(kb_id=kb_pk, type_pk=type_pk, new_type=new_type, created_at=now)

        keyed: dict[str, dict[str, Any]] = {}
        for row in rows:
            if row["key"] is not None:
                first = keyed.setdefault(row["key"], row)
                _check_same_payload(row["key"], first["payload_hash"], row["payload_hash"])
        keyless = [row for row in rows if row["key"] is None]

        inserted: list[dict[str, Any]] = []
        by_key: dict[str, PointResult] = {}
        if keyless:
            ids = session.scalars(
                insert(_POINTS).returning(_POINTS.c.id, sort_by_parameter_order=True), keyless
            ).all()
            for row, point_id in zip(keyless, ids, strict=True):
                row["id"] = point_id
            inserted.extend(keyless)
        if keyed:
            stmt = insert_ignoring_conflicts(session, _POINTS, ["kb_id", "key"])
            for point_id, key in session.execute(
                stmt.returning(_POINTS.c.id, _POINTS.c.key), list(keyed.values())
            ):
                keyed[key]["id"] = point_id
                inserted.append(keyed[key])
            repeated = [k for k, row in keyed.items() if "id" not in row]
            by_key = {}
            for key, (result, stored_hash) in _stored_results(session, kb_pk, repeated).items():
                _check_same_payload(key, stored_hash, keyed[key]["payload_hash"])
                by_key[key] = result

        _count(session, inserted, now)
        type_ids = {pk: type_id for type_id, (pk, _) in types.items()}
        results = []
        for graph, row in zip(resolved, rows, strict=True):
            key = row["key"]
            if key is not None and key in by_key:
                results.append(by_key[key])
                continue
            source = keyed[key] if key is not None else row
            results.append(
                PointResult(
                    type_id=graph.type_id, point_id=source["id"], new_type=source["new_type"]
                )
            )
        touched = frozenset(type_ids[row["type_pk"]] for row in inserted)
    n_new_types = sum(1 for _, created in types.values() if created)
    return PostOutcome(results, touched, n_new=len(inserted), n_new_types=n_new_types)


def _lock_types(session: Session, type_pks: list[int]) -> None:
    """On PostgreSQL, lock the post's type rows (in id order: no deadlock) before its points
    take their ids, so that the posts of one type commit in the order of their point ids: a
    reader that loads a type's points after its last seen id (the surrogate engine, on every
    replica) then never skips a point committed late under a lower id. SQLite's writers
    already queue for the whole database."""
    if session.get_bind().dialect.name == "postgresql" and type_pks:
        session.execute(
            select(_TYPES.c.id)
            .where(_TYPES.c.id.in_(sorted(type_pks)))
            .order_by(_TYPES.c.id)
            .with_for_update()
        )


def _stored_results(
    session: Session, kb_pk: int, keys: list[str]
) -> dict[str, tuple[PointResult, str | None]]:
    """The first answer of each stored key, with the payload hash stored under it."""
    out: dict[str, tuple[PointResult, str | None]] = {}
    for start in range(0, len(keys), 500):
        chunk = keys[start : start + 500]
        rows = session.execute(
            select(
                PointRow.key, PointRow.id, PointRow.new_type, TypeRow.type_id, PointRow.payload_hash
            )
            .join(TypeRow, TypeRow.id == PointRow.type_pk)
            .where(PointRow.kb_id == kb_pk, PointRow.key.in_(chunk))
        )
        for key, point_id, new_type, type_id, payload_hash in rows:
            result = PointResult(type_id=type_id, point_id=point_id, new_type=new_type)
            out[cast(str, key)] = (result, payload_hash)  # a key of `chunk`: not null
    return out


def _count(session: Session, inserted: list[dict[str, Any]], now: Any) -> None:
    """Add the new points to their types' counters, in type order (no lock-order deadlock)."""
    totals: dict[int, list[int]] = defaultdict(lambda: [0, 0])
    for row in inserted:
        totals[row["type_pk"]][0] += 1
        totals[row["type_pk"]][1] += 0 if row["feasible"] else 1
    if totals:
        session.execute(
            _COUNT,
            [
                {"pk": pk, "n": n, "n_infeasible": n_inf, "now": now}
                for pk, (n, n_inf) in sorted(totals.items())
            ],
        )


def _readable(value: Any, depth: int = 1) -> Any:
    """A stored `source` as it can be answered: a part nested deeper than MAX_SOURCE_DEPTH
    (stored before ingest bounded the depth) is given as its JSON text, so that the type's
    points stay readable."""
    if not isinstance(value, dict | list):
        return value
    if depth > MAX_SOURCE_DEPTH:
        return json.dumps(value)
    if isinstance(value, dict):
        return {k: _readable(v, depth + 1) for k, v in value.items()}
    return [_readable(v, depth + 1) for v in value]


def point_out(row: PointRow, type_id: str) -> PointOut:
    source = {name: getattr(row, name) for name in PROVENANCE if getattr(row, name) is not None}
    source.update(_readable(row.extra or {}))
    return PointOut(
        point_id=row.id,
        type_id=type_id,
        x=row.x,
        feasible=row.feasible,
        source=source or None,
        key=row.key,
        created_at=row.created_at,
    )


@dataclass(frozen=True)
class PointFilter:
    """Which of a type's points to read: a label, a task, a run, a worker (None: any) and a
    storage time range (`since` inclusive, `until` exclusive)."""

    feasible: bool | None = None
    task: str | None = None
    run: str | None = None
    worker: str | None = None
    since: datetime | None = None
    until: datetime | None = None

    def conditions(self) -> list[ColumnElement[bool]]:
        """The WHERE conditions of this filter (none: every point)."""
        out: list[ColumnElement[bool]] = []
        if self.feasible is not None:
            out.append(PointRow.feasible.is_(self.feasible))
        for column, value in (
            (PointRow.task, self.task),
            (PointRow.run, self.run),
            (PointRow.worker, self.worker),
        ):
            if value is not None:
                out.append(column == value)
        if self.since is not None:
            out.append(PointRow.created_at >= self.since)
        if self.until is not None:
            out.append(PointRow.created_at < self.until)
        return out

    def apply(self, query: Select[Any]) -> Select[Any]:
        return query.where(*self.conditions())


def parse_cursor(cursor: str | None) -> int | None:
    """A point id this server gave out as `next_cursor`: ASCII digits within 64 bits."""
    if cursor is None or cursor == "":
        return None
    if not (cursor.isascii() and cursor.isdigit()) or len(cursor) > 19 or int(cursor) > INT64:
        raise InvalidInput(f"cursor: {cursor!a} is not a cursor this server gave out")
    return int(cursor)


def list_points(
    store: Store,
    kb: str,
    type_id: str,
    *,
    limit: int,
    cursor: str | None,
    where: PointFilter | None = None,
) -> PointsPage:
    """A page of a type's points in insertion order, those `where` admits; `next_cursor` is
    None on the last page."""
    after = parse_cursor(cursor)
    with store.transaction() as session:
        row = type_row(session, kb, type_id)
        query = (where or PointFilter()).apply(select(PointRow).where(PointRow.type_pk == row.id))
        if after is not None:
            query = query.where(PointRow.id > after)
        points = list(session.scalars(query.order_by(PointRow.id).limit(limit + 1)))
    more = len(points) > limit
    points = points[:limit]
    return PointsPage(
        points=[point_out(p, type_id) for p in points],
        next_cursor=str(points[-1].id) if more else None,
    )


def points_since(store: Store, kb: str, request: PointsSinceIn) -> PointsSinceOut:
    """Points of the watched types stored after the cursor, in id order. The cursor is a point
    id of the whole store: the highest at the time of the read, unless the limit cut the answer
    short, so that a caller's next request skips what this one has looked at (its own points
    included) rather than reading it again."""
    after = request.after_point_id
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
        top = session.scalar(select(func.max(PointRow.id))) or 0
        if after is None or not request.type_ids:
            return PointsSinceOut(points=[], cursor=max(top, after or 0))
        watched = select(TypeRow.id, TypeRow.type_id).where(
            TypeRow.kb_id == kb_pk, TypeRow.type_id.in_(sorted(set(request.type_ids)))
        )
        type_ids: dict[int, str] = {pk: type_id for pk, type_id in session.execute(watched)}
        query = select(*_LIVE_COLUMNS).where(
            PointRow.type_pk.in_(list(type_ids)), PointRow.id > after, PointRow.id <= top
        )
        if request.exclude_run is not None:
            query = query.where(or_(PointRow.run.is_(None), PointRow.run != request.exclude_run))
        rows = session.execute(query.order_by(PointRow.id).limit(request.limit + 1)).all()
    more = len(rows) > request.limit
    rows = rows[: request.limit]
    points = [_live_point(row, type_ids) for row in rows]
    cursor = rows[-1][0] if more else max(top, after)
    return PointsSinceOut(points=points, cursor=cursor, more=more)


_LIVE_COLUMNS = (
    PointRow.id,
    PointRow.type_pk,
    PointRow.x,
    PointRow.feasible,
    PointRow.run,
    PointRow.rollout,
)


def _live_point(row: Any, type_ids: dict[int, str]) -> LivePoint:
    pid, pk, x, feasible, run, rollout = row
    return LivePoint(
        point_id=pid, type_id=type_ids[pk], x=x, feasible=feasible, run=run, rollout=rollout
    )

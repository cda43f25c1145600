"""Reading a knowledge base the way a person browses it (for the dashboard): a type's points
filtered, in either order, paged both ways; a page of types with their provenance in a fixed
number of queries; and the points' history. Read-only."""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import func, select

from client.models import PointOut, TypeSummary
from server.db import Store
from server.errors import NotFound
from server.orm import PointRow, TypeRow
from server.services.kbs import kb_id
from server.services.points import PointFilter, point_out
from server.services.types import summary, type_row


@dataclass(frozen=True)
class PointsView:
    """One page in display order; `after` opens the next page, `before` the previous one
    (None where there is none)."""

    points: list[PointOut]
    after: int | None
    before: int | None
    n_matching: int


def browse_points(
    store: Store,
    kb: str,
    type_id: str,
    *,
    limit: int,
    after: int | None = None,
    before: int | None = None,
    newest_first: bool = False,
    where: PointFilter | None = None,
) -> PointsView:
    """Keyset pages over point ids: `after` continues past a point, `before` goes back from
    one (in display order); both None is the first page."""
    where = where or PointFilter()
    with store.transaction() as session:
        type_pk = type_row(session, kb, type_id).id
        base = where.apply(select(PointRow).where(PointRow.type_pk == type_pk))
        n_matching = session.scalar(
            where.apply(select(func.count(PointRow.id)).where(PointRow.type_pk == type_pk))
        )
        backwards = before is not None
        # Walking toward lower ids: newest first going forward, or oldest first going back.
        down = newest_first != backwards
        query = base.order_by(PointRow.id.desc() if down else PointRow.id)
        cursor = before if backwards else after
        if cursor is not None:
            query = query.where(PointRow.id < cursor if down else PointRow.id > cursor)
        rows = list(session.scalars(query.limit(limit + 1)))
    more = len(rows) > limit
    rows = rows[:limit]
    if backwards:
        rows.reverse()
    first = rows[0].id if rows else None
    last = rows[-1].id if rows else None
    next_after = last if (more and not backwards) or (backwards and rows) else None
    prev_before = first if (more and backwards) or (after is not None and rows) else None
    return PointsView(
        points=[point_out(r, type_id) for r in rows],
        after=next_after,
        before=prev_before,
        n_matching=int(n_matching or 0),
    )


def one_point(store: Store, kb: str, type_id: str, point_id: int) -> PointOut:
    """A point of this type by its id (NotFound when the type has no such point)."""
    with store.transaction() as session:
        type_pk = type_row(session, kb, type_id).id
        row = session.scalar(
            select(PointRow).where(PointRow.id == point_id, PointRow.type_pk == type_pk)
        )
        if row is None:
            raise NotFound(f"type {type_id} has no point #{point_id}")
        return point_out(row, type_id)


def point_in_kb(store: Store, kb: str, point_id: int) -> PointOut:
    """A point of the knowledge base by its id, whatever its type (NotFound if none)."""
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
        found = session.execute(
            select(PointRow, TypeRow.type_id)
            .join(TypeRow, TypeRow.id == PointRow.type_pk)
            .where(PointRow.id == point_id, PointRow.kb_id == kb_pk)
        ).first()
        if found is None:
            raise NotFound(f"knowledge base {kb!r} has no point #{point_id}")
        return point_out(found[0], found[1])


def newest_points(
    store: Store, kb: str, type_id: str, limit: int
) -> list[tuple[int, dict[str, Any], bool]]:
    """The type's newest `limit` points as (id, decision values, label), oldest first."""
    with store.transaction() as session:
        type_pk = type_row(session, kb, type_id).id
        rows = session.execute(
            select(PointRow.id, PointRow.x, PointRow.feasible)
            .where(PointRow.type_pk == type_pk)
            .order_by(PointRow.id.desc())
            .limit(limit)
        ).all()
    return [(int(pid), x, bool(ok)) for pid, x, ok in reversed(rows)]


@dataclass(frozen=True)
class TypeRowView:
    summary: TypeSummary
    tasks: list[tuple[str, int]]  # the most frequent tasks, most points first
    n_tasks: int
    n_runs: int


@dataclass(frozen=True)
class TypesPage:
    rows: list[TypeRowView]
    total: int
    offset: int
    limit: int


def types_page(store: Store, kb: str, *, offset: int, limit: int, top: int = 3) -> TypesPage:
    """A page of the knowledge base's types, most recently updated first, each with its top
    tasks and its task and run counts: four queries, however many types the page holds."""
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
        total = session.scalar(select(func.count(TypeRow.id)).where(TypeRow.kb_id == kb_pk))
        rows = list(
            session.scalars(
                select(TypeRow)
                .where(TypeRow.kb_id == kb_pk)
                .order_by(TypeRow.updated_at.desc(), TypeRow.id)
                .offset(offset)
                .limit(limit)
            )
        )
        pks = [r.id for r in rows]
        per_task: dict[int, list[tuple[str, int]]] = defaultdict(list)
        for pk, task, n in session.execute(
            select(PointRow.type_pk, PointRow.task, func.count(PointRow.id))
            .where(PointRow.type_pk.in_(pks), PointRow.task.isnot(None))
            .group_by(PointRow.type_pk, PointRow.task)
        ):
            per_task[pk].append((str(task), int(n)))
        runs = dict(
            session.execute(
                select(PointRow.type_pk, func.count(func.distinct(PointRow.run)))
                .where(PointRow.type_pk.in_(pks))
                .group_by(PointRow.type_pk)
            ).all()
        )
        views = []
        for r in rows:
            tasks = sorted(per_task[r.id], key=lambda kv: (-kv[1], kv[0]))
            views.append(TypeRowView(summary(r), tasks[:top], len(tasks), int(runs.get(r.id, 0))))
    return TypesPage(views, int(total or 0), offset, limit)


@dataclass
class HistoryBucket:
    """Points stored in one stretch of time, counted per series (a task, or a type)."""

    start: datetime
    end: datetime
    n: Counter[str] = field(default_factory=Counter)
    n_feasible: Counter[str] = field(default_factory=Counter)


@dataclass(frozen=True)
class History:
    buckets: list[HistoryBucket]
    series: list[str]  # most points first
    totals: dict[str, int]


NO_TASK = "(no task)"


def history(
    store: Store, kb: str, type_id: str | None = None, *, buckets: int = 30, max_series: int = 6
) -> History:
    """Points and feasible points per stretch of storage time: for one type split by task,
    for a whole knowledge base split by type (failure and short id). Series past
    `max_series` are summed into `other`."""
    with store.transaction() as session:
        if type_id is not None:
            type_pk = type_row(session, kb, type_id).id
            query = select(PointRow.created_at, PointRow.feasible, PointRow.task).where(
                PointRow.type_pk == type_pk
            )
            rows = [(t, ok, task or NO_TASK) for t, ok, task in session.execute(query)]
        else:
            kb_pk = kb_id(session, kb)
            names = {
                pk: f"{failure} {tid[:6]}"
                for pk, failure, tid in session.execute(
                    select(TypeRow.id, TypeRow.failure, TypeRow.type_id).where(
                        TypeRow.kb_id == kb_pk
                    )
                )
            }
            query = select(PointRow.created_at, PointRow.feasible, PointRow.type_pk).where(
                PointRow.kb_id == kb_pk
            )
            rows = [(t, ok, names[pk]) for t, ok, pk in session.execute(query)]
    totals = Counter(name for _, _, name in rows)
    kept = [name for name, _ in totals.most_common(max_series)]
    if len(totals) > max_series:
        kept = kept[: max_series - 1]
    series = [*kept, "other"] if len(totals) > len(kept) else kept
    if not rows:
        return History([], [], {})
    times = [t for t, _, _ in rows]
    lo, hi = min(times), max(times)
    span = max((hi - lo).total_seconds(), 1e-6)
    out = [
        HistoryBucket(lo + (hi - lo) * (k / buckets), lo + (hi - lo) * ((k + 1) / buckets))
        for k in range(buckets)
    ]
    for t, ok, name in rows:
        k = min(int((t - lo).total_seconds() / span * buckets), buckets - 1)
        key = name if name in kept else "other"
        out[k].n[key] += 1
        out[k].n_feasible[key] += 1 if ok else 0
    merged = Counter({name: totals[name] for name in kept})
    if "other" in series:
        merged["other"] = sum(n for name, n in totals.items() if name not in kept)
    return History(out, series, dict(merged))

"""Reading a knowledge base the way a person browses it (for the dashboard): a type's points
filtered, in either order, paged both ways; a page of types with their provenance in a fixed
number of queries; and the points' history. Read-only."""

from __future__ import annotations

import itertools
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import case, func, select

from contract.models import PointOut, TypeSummary
from server.db import Store
from server.errors import NotFound
from server.orm import KnowledgeBaseRow, PointRow, TypeRow
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


@dataclass(frozen=True)
class TaskShare:
    """One task's part of a type: its points, how many feasible, when they were stored."""

    task: str
    n: int
    n_feasible: int
    first: datetime
    last: datetime


def per_task(store: Store, kb: str, type_id: str) -> list[TaskShare]:
    """The type's points split by task, most points first: one type compared across tasks."""
    with store.transaction() as session:
        type_pk = type_row(session, kb, type_id).id
        rows = session.execute(
            select(
                PointRow.task,
                func.count(PointRow.id),
                func.sum(case((PointRow.feasible.is_(True), 1), else_=0)),
                func.min(PointRow.created_at),
                func.max(PointRow.created_at),
            )
            .where(PointRow.type_pk == type_pk)
            .group_by(PointRow.task)
        ).all()
    shares = [
        TaskShare(task or NO_TASK, int(n), int(ok or 0), first, last)
        for task, n, ok, first, last in rows
    ]
    return sorted(shares, key=lambda s: (-s.n, s.task))


def most_recent_kb(store: Store) -> str | None:
    """The knowledge base whose types were updated last (None when no base has a type)."""
    with store.transaction() as session:
        found = session.execute(
            select(KnowledgeBaseRow.name)
            .join(TypeRow, TypeRow.kb_id == KnowledgeBaseRow.id)
            .order_by(TypeRow.updated_at.desc(), TypeRow.id.desc())
            .limit(1)
        ).first()
    return None if found is None else str(found[0])


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
    """Points stored in one stretch (of time, of the points in storage order, or one or more
    runs), counted per series (a task, or a type); `label` names the stretch."""

    start: datetime
    end: datetime
    label: str = ""
    n: Counter[str] = field(default_factory=Counter)
    n_feasible: Counter[str] = field(default_factory=Counter)


@dataclass(frozen=True)
class History:
    buckets: list[HistoryBucket]
    series: list[str]  # most points first
    totals: dict[str, int]
    axis: str = "time"
    # Idle stretches left out of a time axis: (the bucket they come before, their length in s).
    gaps: list[tuple[int, float]] = field(default_factory=list)


NO_TASK = "(no task)"
NO_RUN = "(no run)"
AXES = ("time", "point", "run")
IDLE_FACTOR = 20.0  # a pause this many times the median gap between points is idle...
IDLE_MIN_S = 60.0  # ...and at least this long


def history(
    store: Store,
    kb: str,
    type_id: str | None = None,
    *,
    axis: str = "time",
    buckets: int = 30,
    max_series: int = 6,
) -> History:
    """Points and feasible points per stretch, for one type split by task, for a whole
    knowledge base split by type (failure and short id); series past `max_series` are summed
    into `other`. The stretches: of storage time with idle pauses left out (`time`), of the
    points in storage order (`point`), or runs in the order they started (`run`)."""
    with store.transaction() as session:
        if type_id is not None:
            type_pk = type_row(session, kb, type_id).id
            of_type = select(
                PointRow.id, PointRow.created_at, PointRow.feasible, PointRow.run, PointRow.task
            ).where(PointRow.type_pk == type_pk)
            rows = [
                (pid, t, ok, run, task or NO_TASK)
                for pid, t, ok, run, task in session.execute(of_type.order_by(PointRow.id))
            ]
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
            of_kb = select(
                PointRow.id, PointRow.created_at, PointRow.feasible, PointRow.run, PointRow.type_pk
            ).where(PointRow.kb_id == kb_pk)
            rows = [
                (pid, t, ok, run, names[pk])
                for pid, t, ok, run, pk in session.execute(of_kb.order_by(PointRow.id))
            ]
    totals = Counter(row[4] for row in rows)
    kept = [name for name, _ in totals.most_common(max_series)]
    if len(totals) > max_series:
        kept = kept[: max_series - 1]
    series = [*kept, "other"] if len(totals) > len(kept) else kept
    if not rows:
        return History([], [], {}, axis)
    rows.sort(key=lambda row: (row[1], row[0]))
    gaps: list[tuple[int, float]] = []
    if axis == "point":
        out, where = _by_point(rows, buckets)
    elif axis == "run":
        out, where = _by_run(rows, buckets)
    else:
        out, where, gaps = _by_active_time(rows, buckets)
    for k, (_, _, ok, _, name) in enumerate(rows):
        key = name if name in kept else "other"
        out[where[k]].n[key] += 1
        out[where[k]].n_feasible[key] += 1 if ok else 0
    merged = Counter({name: totals[name] for name in kept})
    if "other" in series:
        merged["other"] = sum(n for name, n in totals.items() if name not in kept)
    return History(out, series, dict(merged), axis, gaps)


Row = tuple[int, datetime, bool, str | None, str]
Buckets = tuple[list[HistoryBucket], list[int]]  # the buckets, and each row's bucket


def _by_point(rows: list[Row], buckets: int) -> Buckets:
    """Equal shares of the points in storage order."""
    n = len(rows)
    count = min(buckets, n)
    out = []
    for k in range(count):
        lo, hi = k * n // count, (k + 1) * n // count - 1
        out.append(HistoryBucket(rows[lo][1], rows[hi][1], f"points {lo + 1}-{hi + 1}"))
    return out, [k * count // n for k in range(n)]


def _by_run(rows: list[Row], buckets: int) -> Buckets:
    """A bucket per run in the order the runs started (consecutive runs share one when there
    are more than `buckets`)."""
    order: dict[str, int] = {}
    for row in rows:
        order.setdefault(row[3] or NO_RUN, len(order))
    names = list(order)
    per = max(1, -(-len(names) // buckets))
    out = []
    for k in range(0, len(names), per):
        group = names[k : k + per]
        label = f"run {group[0]}" if len(group) == 1 else f"runs {k + 1}-{k + len(group)}"
        mine = [row[1] for row in rows if order[row[3] or NO_RUN] // per == k // per]
        out.append(HistoryBucket(min(mine), max(mine), label))
    return out, [order[row[3] or NO_RUN] // per for row in rows]


def _by_active_time(
    rows: list[Row], buckets: int
) -> tuple[list[HistoryBucket], list[int], list[tuple[int, float]]]:
    """Buckets over the time points were arriving: a pause longer than IDLE_FACTOR times the
    median gap (and IDLE_MIN_S) is left out, and reported as a gap before its bucket."""
    times = [row[1] for row in rows]
    steps = [(b - a).total_seconds() for a, b in itertools.pairwise(times)]
    positive = sorted(x for x in steps if x > 0)
    median = positive[len(positive) // 2] if positive else 0.0
    idle = max(IDLE_MIN_S, IDLE_FACTOR * median)
    active = [0.0]
    pauses: list[tuple[int, float]] = []  # (the point after the pause, its length)
    for k, step in enumerate(steps):
        if step > idle:
            pauses.append((k + 1, step))
            active.append(active[-1])
        else:
            active.append(active[-1] + step)
    span = max(active[-1], 1e-6)
    where = [min(int(a / span * buckets), buckets - 1) for a in active]
    out = []
    for k in range(buckets):
        inside = [times[i] for i, b in enumerate(where) if b == k]
        start, end = (min(inside), max(inside)) if inside else (times[0], times[0])
        out.append(HistoryBucket(start, end, _clock(start, end)))
    return out, where, [(where[i], length) for i, length in pauses]


def _clock(start: datetime, end: datetime) -> str:
    return (
        start.strftime("%Y-%m-%d %H:%M:%S")
        + ("" if end == start else "-" + end.strftime("%H:%M:%S"))
        + " UTC"
    )

"""Who fed the knowledge base: the tasks, runs and workers behind a type's points, and the
workers that posted recently. Read-only; for the dashboard."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, cast

from sqlalchemy import func, select

from server.db import Store
from server.orm import KnowledgeBaseRow, PointRow
from server.services.kbs import kb_id
from server.services.types import type_row


@dataclass(frozen=True)
class SourceCount:
    """One provenance value (a task, run or worker name) and how many points carry it."""

    name: str
    n_points: int


@dataclass(frozen=True)
class Provenance:
    """The top values of each provenance field, and how many distinct values each has."""

    tasks: list[SourceCount]
    runs: list[SourceCount]
    workers: list[SourceCount]
    n_tasks: int
    n_runs: int
    n_workers: int


@dataclass(frozen=True)
class WorkerActivity:
    kb: str
    worker: str
    n_points: int
    last_seen: datetime


def type_provenance(store: Store, kb: str, type_id: str, *, limit: int = 20) -> Provenance:
    """The most frequent tasks, runs and workers among a type's points (NotFound if unknown)."""
    with store.transaction() as session:
        type_pk = type_row(session, kb, type_id).id

        def top(column: Any) -> list[SourceCount]:
            n = func.count(PointRow.id)
            rows = session.execute(
                select(column, n)
                .where(PointRow.type_pk == type_pk, column.isnot(None))
                .group_by(column)
                .order_by(n.desc(), column)
                .limit(limit)
            )
            return [SourceCount(str(name), int(count)) for name, count in rows]

        distinct = session.execute(
            select(
                func.count(func.distinct(PointRow.task)),
                func.count(func.distinct(PointRow.run)),
                func.count(func.distinct(PointRow.worker)),
            ).where(PointRow.type_pk == type_pk)
        ).one()
        return Provenance(
            tasks=top(PointRow.task),
            runs=top(PointRow.run),
            workers=top(PointRow.worker),
            n_tasks=int(distinct[0]),
            n_runs=int(distinct[1]),
            n_workers=int(distinct[2]),
        )


def recent_workers(store: Store, kb: str | None = None, *, limit: int = 20) -> list[WorkerActivity]:
    """Workers by their latest post, newest first (all knowledge bases when `kb` is None)."""
    with store.transaction() as session:
        last = func.max(PointRow.created_at).label("last_seen")
        query = (
            select(KnowledgeBaseRow.name, PointRow.worker, func.count(PointRow.id), last)
            .join(KnowledgeBaseRow, KnowledgeBaseRow.id == PointRow.kb_id)
            .where(PointRow.worker.isnot(None))
            .group_by(KnowledgeBaseRow.name, PointRow.worker)
            .order_by(last.desc())
            .limit(limit)
        )
        if kb is not None:
            query = query.where(PointRow.kb_id == kb_id(session, kb))
        return [
            WorkerActivity(kb_name, cast(str, worker), int(count), _utc(last_seen))
            for kb_name, worker, count, last_seen in session.execute(query)
        ]


def _utc(value: datetime) -> datetime:
    """`max()` over a column bypasses the column type on SQLite: it comes back naive."""
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)

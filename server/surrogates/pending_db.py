"""The pending book in the database, so that planners asking different replicas of one service
are pushed apart as those asking one replica are.

Rows of `cp_pending` under the knowledge base's row: a suggestion's values, its constraint
bindings and when it expires (wall-clock UTC, as replicas share no monotonic clock). Matching a
new point against the entries is `surrogate.pending.answers`, the in-process book's own rule; a
knowledge base holds at most `MAX_PER_KB` live entries, so reading them all is one short query.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import timedelta
from typing import Any, cast

from sqlalchemy import CursorResult, Table, delete, func, select

from server.db import Store
from server.orm import KnowledgeBaseRow, PendingRow, utcnow
from surrogate.encoding import Value
from surrogate.pending import MAX_PER_KB, PendingEntry, answers

Binds = Sequence[tuple[str, Mapping[str, str]]]


def _kb(kb: str) -> Any:
    return select(KnowledgeBaseRow.id).where(KnowledgeBaseRow.name == kb).scalar_subquery()


def _entry(row: PendingRow) -> PendingEntry:
    binds = tuple((t, tuple((label, var) for label, var in bind)) for t, bind in row.binds)
    return PendingEntry(row.x, binds, row.expires_at.timestamp())


class DatabasePendingBook:
    """`surrogate.pending.Pending` on the service's database (any backend; used on PostgreSQL,
    where replicas share it)."""

    def __init__(self, store: Store, ttl_s: float) -> None:
        self.store = store
        self.ttl_s = ttl_s

    def add(self, kb: str, x: Mapping[str, Value], binds: Binds) -> None:
        self._write(kb, [(x, binds)])

    def _write(self, kb: str, entries: Sequence[tuple[Mapping[str, Value], Binds]]) -> None:
        now = utcnow()
        rows = [
            {
                "kb_id": _kb(kb),
                "x": dict(x),
                "binds": [[t, sorted(b.items())] for t, b in binds],
                "expires_at": now + timedelta(seconds=self.ttl_s),
            }
            for x, binds in entries
        ]
        gone = PendingRow.expires_at <= now
        with self.store.transaction(write=True) as session:
            session.execute(delete(PendingRow).where(PendingRow.kb_id == _kb(kb), gone))
            for row in rows:
                session.execute(cast(Table, PendingRow.__table__).insert().values(row))

    def _live(self, kb: str) -> list[tuple[int, PendingEntry]]:
        """The newest `MAX_PER_KB` live entries (newest first), with their row ids."""
        with self.store.transaction() as session:
            rows = session.scalars(
                select(PendingRow)
                .where(PendingRow.kb_id == _kb(kb), PendingRow.expires_at > utcnow())
                .order_by(PendingRow.id.desc())
                .limit(MAX_PER_KB)
            ).all()
            return [(row.id, _entry(row)) for row in rows]

    def for_request(self, kb: str, type_ids: frozenset[str]) -> list[dict[str, Value]]:
        """As `PendingBook.for_request`: the entries sharing a constraint type with the request
        (for one without constraints, the other unconstrained ones), oldest first."""
        entries = [e for _, e in reversed(self._live(kb))]
        if type_ids:
            return [e.x for e in entries if e.type_ids & type_ids]
        return [e.x for e in entries if not e.binds]

    def answered(self, kb: str, type_id: str, points: Sequence[Mapping[str, Value]]) -> int:
        """Delete the entries that new points of `type_id` answer; how many this call deleted
        (every replica that loads the points asks: the first one deletes)."""
        if not points:
            return 0
        done = [pk for pk, e in self._live(kb) if answers(e, type_id, points)]
        if not done:
            return 0
        with self.store.transaction(write=True) as session:
            deleted = delete(PendingRow).where(PendingRow.id.in_(done))
            result = cast(CursorResult[Any], session.execute(deleted))
            return int(result.rowcount or 0)

    def count(self, kb: str) -> int:
        with self.store.transaction() as session:
            found = session.scalar(
                select(func.count(PendingRow.id)).where(
                    PendingRow.kb_id == _kb(kb), PendingRow.expires_at > utcnow()
                )
            )
            return min(int(found or 0), MAX_PER_KB)

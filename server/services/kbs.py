"""Knowledge bases: create, list with counts, delete. `default` always exists."""

from __future__ import annotations

from sqlalchemy import delete, func, select
from sqlalchemy.orm import Session

from contract.models import KnowledgeBase
from server.db import Store
from server.errors import Conflict, NotFound
from server.orm import KnowledgeBaseRow, TypeRow, utcnow
from server.sql import insert_ignoring_conflicts

DEFAULT_KB = "default"


def ensure_kb(session: Session, name: str) -> None:
    """Create the knowledge base `name` unless it exists (safe when racing another process)."""
    stmt = insert_ignoring_conflicts(session, KnowledgeBaseRow, ["name"])
    session.execute(stmt, [{"name": name, "created_at": utcnow()}])


def kb_id(session: Session, name: str) -> int:
    """The row id of knowledge base `name`, or NotFound."""
    found = session.scalar(select(KnowledgeBaseRow.id).where(KnowledgeBaseRow.name == name))
    if found is None:
        raise NotFound(f"knowledge base {name!r} not found")
    return found


def _counts(session: Session, kb_ids: list[int]) -> dict[int, tuple[int, int]]:
    rows = session.execute(
        select(TypeRow.kb_id, func.count(TypeRow.id), func.coalesce(func.sum(TypeRow.n_points), 0))
        .where(TypeRow.kb_id.in_(kb_ids))
        .group_by(TypeRow.kb_id)
    )
    return {kb: (int(n_types), int(n_points)) for kb, n_types, n_points in rows}


def _model(row: KnowledgeBaseRow, counts: dict[int, tuple[int, int]]) -> KnowledgeBase:
    n_types, n_points = counts.get(row.id, (0, 0))
    return KnowledgeBase(
        name=row.name, n_types=n_types, n_points=n_points, created_at=row.created_at
    )


def create_kb(store: Store, name: str) -> KnowledgeBase:
    with store.transaction(write=True) as session:
        if session.scalar(select(KnowledgeBaseRow.id).where(KnowledgeBaseRow.name == name)):
            raise Conflict(f"knowledge base {name!r} already exists")
        row = KnowledgeBaseRow(name=name, created_at=utcnow())
        session.add(row)
        session.flush()
        return _model(row, {})


def list_kbs(store: Store) -> list[KnowledgeBase]:
    with store.transaction() as session:
        rows = list(session.scalars(select(KnowledgeBaseRow).order_by(KnowledgeBaseRow.name)))
        counts = _counts(session, [r.id for r in rows])
        return [_model(r, counts) for r in rows]


def get_kb(store: Store, name: str) -> KnowledgeBase:
    with store.transaction() as session:
        row = session.scalar(select(KnowledgeBaseRow).where(KnowledgeBaseRow.name == name))
        if row is None:
            raise NotFound(f"knowledge base {name!r} not found")
        return _model(row, _counts(session, [row.id]))


def delete_kb(store: Store, name: str) -> None:
    """Delete a knowledge base with its types and points; `default` comes back empty."""
    with store.transaction(write=True) as session:
        kb = kb_id(session, name)
        session.execute(delete(KnowledgeBaseRow).where(KnowledgeBaseRow.id == kb))
        if name == DEFAULT_KB:
            ensure_kb(session, DEFAULT_KB)

"""Found bindings: stored by the planner that found one, read by the planners of the same task
(by skeleton digest, after a cursor) and by users."""

from __future__ import annotations

import logging

from pydantic import ValidationError
from sqlalchemy import func, or_, select

from contract.bindings import BindingIn, BindingOut, BindingsPage
from server.db import Store
from server.errors import Conflict
from server.orm import BindingRow, utcnow
from server.services.kbs import kb_id
from server.sql import insert_ignoring_conflicts

log = logging.getLogger("cpkb.server")


def add_binding(store: Store, kb: str, binding: BindingIn) -> BindingOut:
    """Store a binding; one whose key is stored already stores nothing and gets the stored one
    back (a retry after a lost answer), unless it differs from it (409)."""
    values = {
        "task": binding.task,
        "skeleton": binding.skeleton,
        "run": binding.run,
        "rollout": binding.rollout,
        "bindings": binding.bindings,
    }
    with store.transaction(write=True) as session:
        kb_pk = kb_id(session, kb)
        row = {"kb_id": kb_pk, "key": binding.key, "created_at": utcnow(), **values}
        stmt = insert_ignoring_conflicts(session, BindingRow, ["kb_id", "key"])
        new_id = session.scalar(stmt.values(row).returning(BindingRow.id))
        stored = session.scalar(
            select(BindingRow).where(
                BindingRow.id == new_id
                if new_id is not None
                else (BindingRow.kb_id == kb_pk) & (BindingRow.key == binding.key)
            )
        )
        assert stored is not None  # inserted now, or under its key before
        if any(getattr(stored, name) != value for name, value in values.items()):
            raise Conflict(
                f"idempotency key {binding.key!a} was already used for a different binding: "
                "send a new key for a new binding"
            )
        return _out(stored)


def list_bindings(
    store: Store,
    kb: str,
    *,
    skeleton: str | None,
    task: str | None,
    after: int | None,
    exclude_run: str | None,
    limit: int,
) -> BindingsPage:
    """The bindings after id `after` in id order (all of them without it), of one skeleton
    and task if asked, without those of run `exclude_run`."""
    with store.transaction() as session:
        query = select(BindingRow).where(BindingRow.kb_id == kb_id(session, kb))
        top = session.scalar(select(func.max(BindingRow.id))) or 0
        if skeleton is not None:
            query = query.where(BindingRow.skeleton == skeleton)
        if task is not None:
            query = query.where(BindingRow.task == task)
        if after is not None:
            query = query.where(BindingRow.id > after)
        if exclude_run is not None:
            query = query.where(or_(BindingRow.run.is_(None), BindingRow.run != exclude_run))
        rows = list(
            session.scalars(
                query.where(BindingRow.id <= top).order_by(BindingRow.id).limit(limit + 1)
            )
        )
        more = len(rows) > limit
        rows = rows[:limit]
        cursor = rows[-1].id if more else max(top, after or 0)
        return BindingsPage(bindings=_readable(rows), cursor=cursor)


def _readable(rows: list[BindingRow]) -> list[BindingOut]:
    """The rows as answers, without any that no reader could take: a binding stored before
    the routes refused non-finite numbers (SQLite kept a NaN) is skipped, not answered."""
    found = []
    for row in rows:
        try:
            found.append(_out(row))
        except ValidationError as exc:
            log.warning("binding %d skipped: %s", row.id, exc.errors()[0]["msg"])
    return found


def _out(row: BindingRow) -> BindingOut:
    return BindingOut(
        binding_id=row.id,
        task=row.task,
        skeleton=row.skeleton,
        run=row.run,
        rollout=row.rollout,
        bindings=row.bindings,
        created_at=row.created_at,
    )

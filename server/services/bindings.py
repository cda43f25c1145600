"""Found bindings: stored by the planner that found one, read by the planners of the same task
(by skeleton digest, after a cursor) and by users."""

from __future__ import annotations

from sqlalchemy import func, or_, select

from contract.bindings import BindingIn, BindingOut, BindingsPage
from server.db import Store
from server.orm import BindingRow
from server.services.kbs import kb_id


def add_binding(store: Store, kb: str, binding: BindingIn) -> BindingOut:
    with store.transaction(write=True) as session:
        row = BindingRow(
            kb_id=kb_id(session, kb),
            task=binding.task,
            skeleton=binding.skeleton,
            run=binding.run,
            rollout=binding.rollout,
            bindings=binding.bindings,
        )
        session.add(row)
        session.flush()
        return _out(row)


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
        return BindingsPage(bindings=[_out(row) for row in rows], cursor=cursor)


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

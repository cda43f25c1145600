"""Points as CSV: a type's table (a column per decision value) and a whole knowledge base's
(the decision values as one JSON column, since its types' decisions differ), read page by page.

Every text cell that a spreadsheet would take for a formula (starting with `=`, `+`, `-`, `@`,
a tab or a carriage return) is written with a leading `'`, so that opening an export cannot run
what a planner put in a task name or a worker's name. Numbers are written as they are.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable, Iterator
from typing import Any

from sqlalchemy import select

from contract.models import PointOut
from server.db import Store
from server.orm import PointRow, TypeRow
from server.services.kbs import kb_id
from server.services.points import PROVENANCE, PointFilter, list_points, point_out
from server.services.types import type_row

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def safe_cell(value: Any) -> Any:
    """`value`, a text that starts like a formula quoted with `'` (OWASP's CSV injection rule)."""
    if isinstance(value, str) and value.startswith(FORMULA_STARTS):
        return "'" + value
    return value


class _Lines:
    """A csv writer whose rows are taken back as text, a page at a time."""

    def __init__(self) -> None:
        self.buffer = io.StringIO()
        self.writer = csv.writer(self.buffer)

    def row(self, values: Iterable[Any]) -> None:
        self.writer.writerow([safe_cell(v) for v in values])

    def take(self) -> str:
        text = self.buffer.getvalue()
        self.buffer.seek(0)
        self.buffer.truncate()
        return text


def csv_header(space: dict[str, Any]) -> list[str]:
    """One column per categorical decision, one per dimension of a continuous one."""
    columns = ["point_id", "feasible"]
    for label, domain in space.items():
        if domain["kind"] == "continuous":
            columns.extend(f"{label}[{i}]" for i in range(len(domain["low"])))
        else:
            columns.append(label)
    return [*columns, *PROVENANCE, "key", "created_at"]


def _provenance(p: PointOut) -> list[Any]:
    source = p.source or {}
    return [
        *(source.get(name, "") for name in PROVENANCE),
        p.key or "",
        p.created_at.isoformat() if p.created_at else "",
    ]


def iter_csv(
    store: Store,
    kb: str,
    type_id: str,
    *,
    where: PointFilter | None = None,
    page_size: int = 1000,
) -> Iterator[str]:
    """The type's table as CSV (checks kb and type before the first line)."""
    with store.transaction() as session:
        space = type_row(session, kb, type_id).space
    return _type_lines(store, kb, type_id, space, where, page_size)


def _type_lines(
    store: Store,
    kb: str,
    type_id: str,
    space: dict[str, Any],
    where: PointFilter | None,
    page_size: int,
) -> Iterator[str]:
    lines = _Lines()
    lines.row(csv_header(space))
    yield lines.take()
    cursor: str | None = None
    while True:
        page = list_points(store, kb, type_id, limit=page_size, cursor=cursor, where=where)
        for p in page.points:
            values: list[Any] = [p.point_id, int(p.feasible)]
            for label, domain in space.items():
                v = p.x[label]
                values.extend(v if domain["kind"] == "continuous" else [v])
            lines.row([*values, *_provenance(p)])
        yield lines.take()
        if page.next_cursor is None:
            return
        cursor = page.next_cursor


KB_HEADER = ["type_id", "failure", "point_id", "feasible", "x", *PROVENANCE, "key", "created_at"]


def iter_kb_csv(
    store: Store, kb: str, *, where: PointFilter | None = None, page_size: int = 1000
) -> Iterator[str]:
    """Every point of the knowledge base in id order, its type's id and failure first and its
    decision values as a JSON object (checks the kb before the first line)."""
    with store.transaction() as session:
        kb_pk = kb_id(session, kb)
    return _kb_lines(store, kb_pk, where or PointFilter(), page_size)


def _kb_lines(store: Store, kb_pk: int, where: PointFilter, page_size: int) -> Iterator[str]:
    lines = _Lines()
    lines.row(KB_HEADER)
    yield lines.take()
    after = 0
    while True:
        query = (
            select(PointRow, TypeRow.type_id, TypeRow.failure)
            .join(TypeRow, TypeRow.id == PointRow.type_pk)
            .where(PointRow.kb_id == kb_pk, PointRow.id > after, *where.conditions())
        )
        with store.transaction() as session:
            rows = session.execute(query.order_by(PointRow.id).limit(page_size)).all()
            page = [(point_out(r, type_id), type_id, failure) for r, type_id, failure in rows]
        for p, type_id, failure in page:
            x = json.dumps(p.x, separators=(",", ":"))
            lines.row([type_id, failure, p.point_id, int(p.feasible), x, *_provenance(p)])
        yield lines.take()
        if len(page) < page_size:
            return
        after = page[-1][0].point_id

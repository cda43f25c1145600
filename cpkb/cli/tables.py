"""Tables in a terminal that never cut a name: the directory every task name shares is said
once in the title (`my-suite/ws00/desk` shows as `ws00/desk`), the name column is as wide as
its longest name (the other columns share what the terminal has left)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

KEEP_PARTS = 2  # a task name keeps its workspace and its own name: ws00/desk


def shared_directory(names: Sequence[str]) -> str:
    """The leading `dir/` parts that every name has, leaving each at least KEEP_PARTS parts."""
    split = [name.split("/") for name in names]
    if not split:
        return ""
    room = min(len(parts) for parts in split) - KEEP_PARTS
    shared: list[str] = []
    for k in range(max(0, room)):
        part = split[0][k]
        if any(parts[k] != part for parts in split):
            break
        shared.append(part)
    return "".join(p + "/" for p in shared)


def whole_names_table(
    headers: Sequence[str],
    rows: Sequence[Sequence[str]],
    title: str,
    *,
    names: int = 1,
    **options: Any,
) -> Any:
    """A rich Table of `rows` whose first `names` columns (a task, a method) show whole."""
    from rich.table import Table

    prefix = shared_directory([row[0] for row in rows])
    if prefix:
        title += f" (tasks under {prefix})"
    table = Table(*headers, title=title, **options)
    shown = [[row[0].removeprefix(prefix), *row[1:]] for row in rows]
    for k in range(names):
        table.columns[k].min_width = max((len(row[k]) for row in shown), default=0)
        table.columns[k].overflow = "fold"
    for row in shown:
        table.add_row(*row)
    return table

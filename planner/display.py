"""A live progress line for one binding search (rich): rollouts, best depth, types active."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Protocol

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

MAX_LABEL = 28  # a task file's long path is cut to its end
BAR_WIDTHS = (6, 40)  # the bar's narrowest and widest
DEPTH = len("best depth 0.00")
TYPES = len("  types 10 active (10 from the KB)")
ELAPSED = len("0:00:00")


class PlanProgress(Protocol):
    """What the line shows of a search (`planner.run.Progress`)."""

    @property
    def rollouts(self) -> int: ...
    @property
    def best_depth(self) -> float: ...
    @property
    def types_active(self) -> int: ...
    @property
    def types_activated(self) -> int: ...


@contextlib.contextmanager
def live_progress(
    label: str, max_rollouts: int, console: Console | None = None
) -> Iterator[Callable[[PlanProgress], None]]:
    """A callback for `run_plan(progress=...)` that draws on stderr while the search runs.

    The line is laid out to fit the terminal, so that rich never has to squeeze it: the
    rollout count and the time keep their room, the bar shrinks, and the details (depth,
    types) are cut short last."""
    console = console or Console(stderr=True)
    count = len(f"{max_rollouts}/{max_rollouts}") + len(" rollouts")
    gaps = 4  # between label, bar, count, time and details (the count holds its own)
    least = count + ELAPSED + gaps + BAR_WIDTHS[0] + DEPTH
    fits = max(8, min(MAX_LABEL, console.width - 1 - least))
    if len(label) > fits:
        label = "…" + label[-(fits - 1) :]
    spare = console.width - 1 - (len(label) + count + ELAPSED + gaps)
    bar_width = max(BAR_WIDTHS[0], min(BAR_WIDTHS[1], spare - DEPTH - TYPES))
    room = max(DEPTH, spare - bar_width)
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(bar_width=bar_width),
        MofNCompleteColumn(),
        TextColumn("rollouts"),
        TimeElapsedColumn(),
        TextColumn("{task.fields[details]}"),
    )
    with Progress(*columns, console=console, transient=False) as bar:
        task = bar.add_task(label, total=max_rollouts, details="")

        def update(p: PlanProgress) -> None:
            details = f"best depth {p.best_depth:.2f}"
            # Only methods with a knowledge base have types; a method without one shows none.
            if p.types_active or p.types_activated:
                details += f"  types {p.types_active} active ({p.types_activated} from the KB)"
            if len(details) > room:
                details = details[: max(0, room - 1)] + "…"
            bar.update(task, completed=p.rollouts, details=details)

        yield update

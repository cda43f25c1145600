"""A live progress line for one binding search (rich): rollouts, best depth, types active."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from planner.run import Progress as PlanProgress


@contextlib.contextmanager
def live_progress(
    label: str, max_rollouts: int, console: Console | None = None
) -> Iterator[Callable[[PlanProgress], None]]:
    """A callback for `run_plan(progress=...)` that draws on stderr while the search runs."""
    console = console or Console(stderr=True)
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("rollouts  best depth {task.fields[depth]:.2f}  types {task.fields[types]}"),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=console, transient=False) as bar:
        task = bar.add_task(label, total=max_rollouts, depth=0.0, types="0")

        def update(p: PlanProgress) -> None:
            types = f"{p.types_active} active ({p.types_activated} from the KB)"
            bar.update(task, completed=p.rollouts, depth=p.best_depth, types=types)

        yield update

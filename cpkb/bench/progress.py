"""A rich progress bar with ETA for the bench: runs done, solved, errors, the last run."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)


class RichProgress:
    """Implements the runner's `Progress`; ETA averages over the last ten minutes of runs."""

    def __init__(self, console: Console | None = None) -> None:
        self._progress = Progress(
            TextColumn("[bold]bench"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[status]}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=console,
            speed_estimate_period=600.0,
        )
        self._task = None
        self._solved = 0
        self._errors = 0

    def start(self, total: int) -> None:
        self._progress.start()
        self._task = self._progress.add_task("bench", total=total, status="")

    def advance(self, ok: bool, record: Mapping[str, Any]) -> None:
        if ok:
            self._solved += bool(record.get("solved"))
            last = f"{record['task']}/{record['method']}/{record['seed']}: {record['rollouts']}"
        else:
            self._errors += 1
            last = f"{record['task']}/{record['method']}/{record['seed']}: error"
        status = f"solved {self._solved}, errors {self._errors}, last {last}"
        self._progress.update(self._task, advance=1, status=status)

    def stop(self) -> None:
        self._progress.stop()

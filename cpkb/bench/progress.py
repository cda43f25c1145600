"""A rich progress bar with ETA for the bench: runs done, solved, errors, the last run."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

BAR_WIDTHS = (6, 40)  # the bar's narrowest and widest
TIME = len("0:00:00")
STATUS = len("solved 100, errors 0, last ws00/regrasp.yaml/cp-bo-transfer/7000: 2000")


def short_task(task: str) -> str:
    """A generated task by its workspace and file (`ws03/desk.yaml`): the suite's directory is
    the same for every run and would push the numbers off the line."""
    path = Path(task)
    return f"{path.parent.name}/{path.name}" if len(path.parts) > 2 else task


class RichProgress:
    """Implements the runner's `Progress`; ETA averages over the last ten minutes of runs.

    The line is laid out for the terminal's width, so that rich never squeezes it: the count
    and the times keep their room, the bar shrinks, and the status is cut short last."""

    def __init__(self, console: Console | None = None) -> None:
        self._console = console or Console()
        self._progress: Progress | None = None
        self._task: TaskID | None = None
        self._solved = 0
        self._errors = 0
        self._room = STATUS

    def start(self, total: int) -> None:
        # "bench", the count, elapsed, "ETA" and remaining, and the six gaps between them all
        fixed = len("bench") + len(f"{total}/{total}") + TIME + len("ETA") + TIME + 6
        spare = self._console.width - 1 - fixed
        bar_width = max(BAR_WIDTHS[0], min(BAR_WIDTHS[1], spare - STATUS))
        self._room = max(12, spare - bar_width)
        self._progress = Progress(
            TextColumn("[bold]bench"),
            BarColumn(bar_width=bar_width),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            TextColumn("{task.fields[status]}"),
            console=self._console,
            speed_estimate_period=600.0,
        )
        self._progress.start()
        self._task = self._progress.add_task("bench", total=total, status="")

    def advance(self, ok: bool, record: Mapping[str, Any]) -> None:
        run = f"{short_task(record['task'])}/{record['method']}/{record['seed']}"
        if ok:
            self._solved += bool(record.get("solved"))
            last = f"{run}: {record['rollouts']}"
        else:
            self._errors += 1
            last = f"{run}: error"
        status = f"solved {self._solved}, errors {self._errors}, last {last}"
        if len(status) > self._room:
            status = status[: self._room - 1] + "…"
        assert self._progress is not None and self._task is not None
        self._progress.update(self._task, advance=1, status=status)

    def stop(self) -> None:
        if self._progress is not None:
            self._progress.stop()

"""The bench's progress line fits the terminal: the count and the ETA survive at 80 columns."""

from __future__ import annotations

import io

from rich.console import Console

from cpkb.bench.progress import RichProgress, short_task


def test_the_line_keeps_count_and_eta_at_80_columns() -> None:
    out = io.StringIO()
    console = Console(file=out, width=80, force_terminal=True, color_system=None)
    progress = RichProgress(console)
    progress.start(1500)
    record = {
        "task": "benchmarks/suites/dev/ws03/regrasp.yaml",
        "method": "cp-bo-transfer",
        "seed": 7003,
        "rollouts": 123,
        "solved": True,
    }
    progress.advance(True, record)
    progress.advance(False, record)
    progress.stop()
    line = out.getvalue().split("\r")[-1].replace("\x1b[2K", "").replace("\x1b[?25h", "")
    line = line.strip("\n")
    assert "2/1500" in line and "ETA" in line and "solved 1, errors 1" in line
    assert len(line) < 80


def test_generated_tasks_are_named_by_workspace_and_file() -> None:
    assert short_task("benchmarks/suites/dev/ws03/regrasp.yaml") == "ws03/regrasp.yaml"
    assert short_task("desk") == "desk"

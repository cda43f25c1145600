"""The progress line of one search fits the terminal: the rollout count survives at 80
columns, and a method without a knowledge base shows no types."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from planner.display import live_progress
from planner.result import Progress


def _final_line(width: int, label: str, types_active: int, types_activated: int) -> str:
    out = io.StringIO()
    console = Console(file=out, width=width, force_terminal=True, color_system=None)
    with live_progress(label, 2000, console=console) as update:
        update(Progress(1234, 2000, 3.5, True, types_active, types_activated, 5.0))
    last = out.getvalue().split("\r")[-1]
    return last.replace("\x1b[2K", "").replace("\x1b[?25h", "").strip("\n")


@pytest.mark.parametrize("width", [60, 80, 120])
@pytest.mark.parametrize("label", ["desk cp-bo", "benchmarks/suites/dev/ws03/regrasp.yaml cp-bo"])
def test_the_final_line_keeps_the_rollout_count_and_fits(width: int, label: str) -> None:
    line = _final_line(width, label, 12, 4)
    assert "1234/2000 rollouts" in line
    assert len(line) < width
    assert "\n" not in line


def test_types_show_only_where_there_are_some() -> None:
    assert "types" not in _final_line(120, "desk quasi-random", 0, 0)
    assert "types 12 active (4 from the KB)" in _final_line(120, "desk cp-bo", 12, 4)

"""`cpkb render` writes a PNG headless; `cpkb tasks` lists the shipped tasks; mistakes are clear."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


def _cpkb(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cpkb", *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
def test_render_writes_a_png_without_a_display(tmp_path: Path) -> None:
    out = tmp_path / "desk.png"
    done = _cpkb("render", "--task", "desk", "--out", str(out), "--binding", '{"#dir1": "front"}')
    assert done.returncode == 0, done.stderr
    assert "transition 0: ok" in done.stdout
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000


def test_tasks_lists_one_line_per_task() -> None:
    done = _cpkb("tasks")
    assert done.returncode == 0, done.stderr
    names = [line.split()[0] for line in done.stdout.splitlines()]
    assert names == ["deskP", "desk", "regrasp", "packP1", "packP2", "packP3", "pack"]


@pytest.mark.slow
def test_render_mistakes_are_one_line_errors(tmp_path: Path) -> None:
    missing = _cpkb("render", "--task", "nowhere", "--out", str(tmp_path / "x.png"))
    assert missing.returncode == 2 and "no such task" in missing.stderr
    bad = _cpkb("render", "--task", "desk", "--out", str(tmp_path / "x.png"), "--binding", "{")
    assert bad.returncode == 2 and "not valid JSON" in bad.stderr
    wrong = _cpkb(
        "render", "--task", "desk", "--out", str(tmp_path / "x.png"), "--binding", '{"#x": 1}'
    )
    assert wrong.returncode == 2 and "not a decision of desk" in wrong.stderr
    for done in (missing, bad, wrong):
        assert "Traceback" not in done.stderr


def test_gui_without_a_display_is_a_clear_error() -> None:
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    done = subprocess.run(
        [sys.executable, "-m", "cpkb", "render", "--task", "desk", "--gui"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert done.returncode == 2
    assert "needs a display" in done.stderr and "Traceback" not in done.stderr

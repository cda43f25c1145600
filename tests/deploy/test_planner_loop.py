"""deploy/planner-loop.sh: a worker goes on past unsolved runs and gives up only on errors."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LOOP = ROOT / "deploy" / "planner-loop.sh"
BIN = Path(sys.executable).parent


def _loop(*args: str, **env: str) -> subprocess.CompletedProcess[str]:
    environment = {**os.environ, "PATH": f"{BIN}:{os.environ['PATH']}", **env}
    return subprocess.run(
        ["sh", str(LOOP), *args], capture_output=True, text=True, env=environment, timeout=600
    )


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("sh") is None, reason="needs a POSIX shell")
def test_an_unsolved_run_does_not_stop_the_worker() -> None:
    # quasi-random needs no knowledge base; one rollout never solves desk, so each run exits 1.
    result = _loop("http://127.0.0.1:9", "default", "desk,deskP", "quasi-random", "1", "1")
    assert result.returncode == 0, result.stderr
    runs = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    assert [r["task"] for r in runs] == ["desk", "deskP"]
    assert not any(r["solved"] for r in runs)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("sh") is None, reason="needs a POSIX shell")
def test_a_worker_that_cannot_reach_its_service_retries_then_gives_up() -> None:
    result = _loop(
        "http://127.0.0.1:9",
        "default",
        "desk",
        "cp-bo",
        "1",
        "1",
        CPKB_WORKER_RETRIES="2",
        CPKB_WORKER_PAUSE_S="0",
    )
    assert result.returncode > 1
    assert result.stderr.count("planner-loop: desk seed") == 2

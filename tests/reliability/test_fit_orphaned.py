"""A fit worker whose server is SIGKILLed while the worker is still starting (its imports take
seconds) leaves too, with anything it started: it knows its server's pid from the start."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import httpx
import pytest
from killable_server import KillableServer, alive, fit_workers
from test_fit_killed import batch

# Bounds for a loaded machine (the worker must finish its imports before it can look), not
# deadlines a test races: a worker that misses its server's death never leaves at all.
APPEARS_S = 120
LEAVES_S = 240


def importing_torch(pid: int) -> bool:
    """The worker has read what its server sent it and is loading torch (its slow part)."""
    try:
        return "libtorch" in Path(f"/proc/{pid}/maps").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.mark.slow
def test_a_fit_worker_leaves_when_its_server_is_killed_while_it_starts(
    db_url: str, tmp_path: Path
) -> None:
    server = KillableServer(db_url, tmp_path)
    server.start()
    try:
        assert server.proc is not None
        with httpx.Client(base_url=server.url, timeout=60) as http:
            assert http.post("/v1/kbs/default/points", json=batch(0, 40)).status_code == 201
        deadline = time.monotonic() + APPEARS_S
        while not any(importing_torch(pid) for pid in fit_workers(server.proc.pid)):
            assert time.monotonic() < deadline, "no fit worker started"
            time.sleep(0.01)
        workers = fit_workers(server.proc.pid, trackers=True)
        server.proc.send_signal(signal.SIGKILL)
        server.proc.wait(timeout=30)
        deadline = time.monotonic() + LEAVES_S
        while left := [pid for pid in workers if alive(pid)]:
            assert time.monotonic() < deadline, f"processes outlived their server: {left}"
            time.sleep(0.2)
    finally:
        server.stop()

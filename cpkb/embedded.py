"""An embedded knowledge base: `cpkb serve` in a subprocess, for one `with` block.

A subprocess rather than a thread, so that the service (and its GP fits) runs on another core
than the planner that uses it, and so that it dies with nothing shared when the block ends.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

from server.cpus import format_cpu_list, spare_cores

# A safety net against a service that hangs, not a measure of a slow start: the wait ends as
# soon as the service answers or exits, and a niced service starting among busy processes
# (its torch import) can take minutes; given up on earlier, it is killed mid-import.
START_TIMEOUT_S = 900.0
STOP_TIMEOUT_S = 10.0


class EmbeddedServiceError(RuntimeError):
    """The embedded service did not come up; the message holds the end of its log."""


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free a moment ago (the caller retries if it is taken meanwhile)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def _tail(path: Path, lines: int = 15) -> str:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return ""
    return "\n".join(text.strip().splitlines()[-lines:])


def wait_ready(url: str, process: subprocess.Popen[bytes], timeout: float) -> bool:
    """Poll `/healthz` until it answers 200 (True), the process exits or time runs out (False).
    One client for every poll: `httpx.get` builds a client, and its SSL context, each time, a
    hundred times the poll's own cost, taken from the service that is starting."""
    deadline = time.monotonic() + timeout
    with httpx.Client(timeout=2.0) as client:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                return False
            try:
                if client.get(f"{url}/healthz").status_code == 200:
                    return True
            except httpx.TransportError:
                pass
            time.sleep(0.1)
    return False


def stop_process(process: subprocess.Popen[bytes], timeout: float = STOP_TIMEOUT_S) -> None:
    """SIGTERM (uvicorn shuts down cleanly), then SIGKILL if it does not stop in time."""
    if process.poll() is not None:
        return
    process.send_signal(signal.SIGTERM)
    try:
        process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


@contextmanager
def service_url(kb_url: str | None, db_url: str | None = None) -> Iterator[str]:
    """`kb_url` as is, or that of an embedded service for the command's planner on `db_url`
    (default: the service's own default database, CPKB_DATABASE_URL or ./cpkb.db, so knowledge
    persists across runs), kept off one core, which the planner gets to itself."""
    if kb_url is not None:
        yield kb_url
        return
    with embedded_service(db_url, planner_cores=1) as url:
        yield url


@contextmanager
def embedded_service(
    db_url: str | None = None,
    *,
    quiet: bool = True,
    start_timeout: float = START_TIMEOUT_S,
    env: dict[str, str] | None = None,
    log_file: Path | None = None,
    planner_cores: int = 0,
) -> Iterator[str]:
    """Run `cpkb serve` on a free loopback port; yields its base URL, stops it on exit.

    `db_url` defaults to the service's own default (CPKB_DATABASE_URL, else ./cpkb.db).
    With `quiet`, the service's log goes to `log_file` (default: a temporary file), and its end
    is quoted if the service fails to start. `planner_cores`: that many of this process's cores
    are left to the planners and the service runs on the others (`server.cpus`), where there
    are others and CPKB_CPU_CORES does not say otherwise.
    """
    command = [sys.executable, "-m", "cpkb", "serve", "--host", "127.0.0.1"]
    if db_url is not None:
        command += ["--db", db_url]
    child_env = {**os.environ, **(env or {})}
    if "CPKB_CPU_CORES" not in child_env and (cores := spare_cores(planner_cores)) is not None:
        child_env["CPKB_CPU_CORES"] = format_cpu_list(cores)
    with tempfile.TemporaryDirectory(prefix="cpkb-embedded-") as tmp:
        log_path = log_file if log_file is not None else Path(tmp) / "service.log"
        for _ in range(3):
            port = free_port()
            url = f"http://127.0.0.1:{port}"
            with open(log_path, "ab") as log:
                output = log if quiet else None
                process = subprocess.Popen(
                    [*command, "--port", str(port)],
                    stdout=output,
                    stderr=subprocess.STDOUT if quiet else None,
                    env=child_env,
                )
            try:
                ready = wait_ready(url, process, start_timeout)
            except BaseException:
                stop_process(process)
                raise
            if ready:
                break
            stop_process(process)
            if "address already in use" not in _tail(log_path).lower():
                raise EmbeddedServiceError(
                    f"the embedded knowledge base did not start (exit {process.returncode}):\n"
                    f"{_tail(log_path)}"
                )
        else:
            raise EmbeddedServiceError("no free port for the embedded knowledge base")
        try:
            yield url
        finally:
            stop_process(process)

"""A real `cpkb serve` child process on a loopback port that tests can kill and restart, and
read-backs of what it stored."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
from collections import Counter
from pathlib import Path

import httpx

from cpkb.embedded import START_TIMEOUT_S, wait_ready

REPO = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class KillableServer:
    """`cpkb serve --db URL` on a fixed port, so that a restart comes back at the same URL."""

    def __init__(self, db_url: str, log_dir: Path, env: dict[str, str] | None = None) -> None:
        self.db_url = db_url
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log_dir = log_dir
        self.env = {k: v for k, v in os.environ.items() if not k.startswith("CPKB_")} | (env or {})
        self.proc: subprocess.Popen | None = None
        self.starts = 0

    def start(self, timeout: float = START_TIMEOUT_S) -> None:
        self.starts += 1
        log = (self.log_dir / f"server-{self.starts}.log").open("wb")
        cmd = [sys.executable, "-m", "cpkb", "serve", "--db", self.db_url]
        cmd += ["--host", "127.0.0.1", "--port", str(self.port)]
        self.proc = subprocess.Popen(
            cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
        log.close()
        if wait_ready(self.url, self.proc, timeout):
            return
        if self.proc.poll() is not None:
            raise RuntimeError(f"server exited ({self.proc.returncode}): {self.log_tail()}")
        raise RuntimeError(f"server not healthy after {timeout} s: {self.log_tail()}")

    def kill(self) -> None:
        """SIGKILL: no shutdown hooks, no flushing; what a power cut or the OOM killer does."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=10)
        self._reap()

    def stop(self) -> None:
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._reap()

    def _reap(self) -> None:
        """SIGKILL anything the dead server left in its process group, so that no test leaks a
        process even if a fit worker failed to follow its server (test_fit_killed checks)."""
        assert self.proc is not None
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL)

    def log_tail(self, n: int = 3000) -> str:
        path = self.log_dir / f"server-{self.starts}.log"
        return path.read_text(errors="replace")[-n:] if path.exists() else ""


def stored_keys(base_url: str, kb: str = "default") -> Counter[str | None]:
    """How many times each idempotency key is stored in `kb`, over every type's points."""
    keys: Counter[str | None] = Counter()
    with httpx.Client(base_url=base_url, timeout=30) as http:
        for t in http.get(f"/v1/kbs/{kb}/types").raise_for_status().json():
            cursor = None
            while True:
                params = {"limit": 1000} | ({"cursor": cursor} if cursor else {})
                page = http.get(f"/v1/kbs/{kb}/types/{t['type_id']}/points", params=params)
                body = page.raise_for_status().json()
                keys.update(p["key"] for p in body["points"])
                cursor = body.get("next_cursor")
                if not cursor:
                    break
    return keys


def kb_point_count(base_url: str, kb: str = "default") -> int:
    kbs = httpx.get(f"{base_url}/v1/kbs", timeout=30).raise_for_status().json()
    return next(k["n_points"] for k in kbs if k["name"] == kb)


def fit_workers(server_pid: int, *, trackers: bool = False) -> list[int]:
    """The server's multiprocessing children (the fit worker; with `trackers`, also any
    resource tracker), from /proc (any thread's)."""
    children = [
        pid
        for task in Path(f"/proc/{server_pid}/task").iterdir()
        for pid in (task / "children").read_text().split()
    ]
    workers = []
    for pid in children:
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
        except FileNotFoundError:
            continue
        tracker = b"resource_tracker" in cmdline
        if b"multiprocessing" in cmdline and (trackers or not tracker):
            workers.append(int(pid))
    return workers


def alive(pid: int) -> bool:
    """Running (not gone, not a zombie waiting to be reaped)."""
    try:
        status = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return status.rsplit(")", 1)[1].split()[0] != "Z"

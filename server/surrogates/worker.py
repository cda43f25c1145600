"""Where the engine's fits run: a child process of its own (the default), or a thread.

The child process is ours, not a pool's: `terminate()` ends it through its public handle, so a
stopping server does not wait for a fit it has no use for, and a worker that dies mid-fit is
seen at once (its sentinel fires) rather than leaving the caller waiting for an answer.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ThreadPoolExecutor
from multiprocessing.connection import Connection, wait
from typing import Any, Protocol

from server.surrogates import fitproc
from surrogate.models import Fit


class WorkerDied(RuntimeError):
    """The fit worker ended before it answered (killed, crashed, or terminated)."""


class Fitter(Protocol):
    def fit(self, *args: Any) -> Fit: ...

    def terminate(self) -> None: ...


def _serve(conn: Connection, threads: int, server_pid: int) -> None:
    """The child's loop: one fit per message, its result or its exception sent back."""
    fitproc.init_worker(threads, server_pid)
    while True:
        try:
            args = conn.recv()
        except EOFError:
            return
        try:
            conn.send((True, fitproc.fit_job(*args)))
        except Exception as exc:  # the server decides what a failed fit means
            conn.send((False, exc))


class ChildProcessFitter:
    """Fits, one at a time, in a spawned child process (gpytorch's Python-heavy training then
    never holds the server's GIL). Starting it raises what `Process.start` raises."""

    def __init__(self, threads: int) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child_end = context.Pipe()
        self._process = context.Process(
            target=_serve, args=(child_end, threads, os.getpid()), name="cpkb-fit", daemon=True
        )
        self._process.start()
        child_end.close()

    def fit(self, *args: Any) -> Fit:
        """The fit's result; its exception re-raised; WorkerDied if the child ended first."""
        try:
            self._conn.send(args)
            wait([self._conn, self._process.sentinel])
            reply: tuple[bool, Any] | None = self._conn.recv() if self._conn.poll() else None
        except (EOFError, OSError) as exc:
            raise WorkerDied(f"the fit worker ended ({exc})") from exc
        if reply is None:
            raise WorkerDied(f"the fit worker ended (exit code {self._process.exitcode})")
        ok, value = reply  # (True, the Fit) or (False, the exception it raised)
        if not ok:
            raise value
        return value

    def terminate(self) -> None:
        """End the child now (a fit in flight is dropped: its caller gets WorkerDied)."""
        self._process.terminate()
        self._process.join(timeout=5)


class ThreadFitter:
    """Fits in a thread of this process: where a child process cannot be started."""

    def __init__(self) -> None:
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cpkb-fit")
        self._executor.submit(fitproc.warm_up)  # runs before the first fit, in the same thread

    def fit(self, *args: Any) -> Fit:
        return self._executor.submit(fitproc.fit_job, *args).result()

    def terminate(self) -> None:
        """Drop queued fits; a fit in flight runs to its end (a thread cannot be stopped)."""
        self._executor.shutdown(wait=False, cancel_futures=True)

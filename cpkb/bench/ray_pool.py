"""The bench's runs as Ray tasks on a running Ray cluster (`cpkb bench --ray ADDRESS`).

Each scenario is one task running the runner's `execute`, so a run on the cluster is the same
run as in the local pool: its own process and PyBullet, every random choice seeded from the
scenario seed. The driver (the `cpkb bench` process) appends each result to runs.jsonl as it
arrives, so resuming, the summary and the plots are the local pool's.

Ray imports `cpkb` on every node by name: the package must be installed on each node (the
same version, in the same Python as the cluster), or shipped with the job's runtime_env
working_dir. Without `--kb-url`, each Ray worker process starts its own embedded service the
first time a run needs one; with it, every run uses that shared service, which must then be
reachable from every node.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import shutil
import socket
import tempfile
import threading
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cpkb.bench.kbs import FIT_WAIT_S, ServiceKbs
from cpkb.bench.runner import Job, execute

INSTALL_HINT = "pip install -e '.[ray]'"
CONNECT_TIMEOUT_S = 10.0


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Fail at once on a head that does not answer: Ray itself retries an unreachable address
    for ever. `auto` (the cluster this machine belongs to) is left to Ray."""
    if address == "auto":
        return
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"--ray takes the head's HOST:PORT (or auto), not {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise ValueError(f"no Ray head answers at {address}: {exc}") from None


def require_ray() -> None:
    """A clear error, not an ImportError deep in a run, when Ray is not installed."""
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ValueError(f"--ray needs Ray, which is not installed ({INSTALL_HINT})") from None


def _crash_record(job: Job, exc: BaseException) -> dict[str, Any]:
    """The error record of a task that died before `execute` could answer (its worker or node
    was lost, or it could not be unpickled there)."""
    s = job.scenario
    return {
        "task": s.task,
        "method": s.method,
        "seed": s.seed,
        "error": f"{type(exc).__name__}: {exc}",
        "traceback": "".join(traceback.format_exception(exc)),
    }


class RayPool:
    """The runs as tasks of one CPU each and no GPU, on the cluster at `address` (its head's
    host:port, or `auto`); the cluster's CPUs, not `--workers`, bound how many run at once.

    Ray gives a task of one CPU OMP_NUM_THREADS=1, which torch and OpenBLAS follow, so no
    runtime_env is needed for the local pool's one-thread-per-run."""

    def __init__(self, address: str) -> None:
        self.address = address
        self._running: dict[Any, Job] = {}
        self._ready: list[Any] = []

    def start(self, jobs: Sequence[Job]) -> None:
        import ray

        check_reachable(self.address)
        try:
            ray.init(address=self.address, log_to_driver=False, logging_level=logging.WARNING)
        except (ConnectionError, RuntimeError) as exc:
            raise ValueError(f"no usable Ray cluster at {self.address}: {exc}") from None
        task = ray.remote(num_cpus=1, num_gpus=0)(execute)
        self._running = {task.remote(job): job for job in jobs}

    def next_result(self, timeout: float) -> tuple[bool, dict[str, Any]] | None:
        import ray

        if not self._ready and self._running:
            refs = list(self._running)
            self._ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
            if not self._ready:
                self._ready, _ = ray.wait(refs, num_returns=1, timeout=timeout)
        if not self._ready:
            return None
        ref = self._ready.pop()
        job = self._running.pop(ref)
        try:
            return ray.get(ref)
        except ray.exceptions.RayError as exc:
            return False, _crash_record(job, exc)

    def stop(self) -> None:
        import ray

        if not ray.is_initialized():
            return
        for ref in self._running:
            with contextlib.suppress(Exception):  # a task that finished meanwhile
                ray.cancel(ref, force=True)
        self._running, self._ready = {}, []
        ray.shutdown()


_service_lock = threading.Lock()
_service_url: str | None = None
SERVICE_DIR_PREFIX = "cpkb-ray-kb-"


def _sweep_service_dirs() -> None:
    """Remove the databases of worker processes that are gone: Ray ends its idle workers
    without running their exit handlers, so each worker clears its predecessors' files."""
    for path in Path(tempfile.gettempdir()).glob(f"{SERVICE_DIR_PREFIX}*-*"):
        pid = path.name.removeprefix(SERVICE_DIR_PREFIX).split("-", 1)[0]
        if pid.isdigit() and not Path(f"/proc/{pid}").exists():
            shutil.rmtree(path, ignore_errors=True)


def _worker_service(token: str | None) -> str:
    """This process's embedded service, started on first use on a SQLite file of its own and
    stopped when the process exits (Ray also ends a worker's children with it, on Linux)."""
    global _service_url
    with _service_lock:
        if _service_url is None:
            from cpkb.embedded import embedded_service

            _sweep_service_dirs()
            tmp = tempfile.mkdtemp(prefix=f"{SERVICE_DIR_PREFIX}{os.getpid()}-")
            stack = contextlib.ExitStack()
            stack.callback(shutil.rmtree, tmp, ignore_errors=True)
            env = {"CPKB_TOKEN": token} if token is not None else None
            _service_url = stack.enter_context(
                embedded_service(f"sqlite:///{Path(tmp) / 'kb.db'}", env=env)
            )
            atexit.register(stack.close)
        return _service_url


@dataclass(frozen=True)
class WorkerKbs:
    """Scenario knowledge bases on an embedded service per Ray worker process: picklable, and
    the service is only started where a run asks for its `url`."""

    token: str | None = None

    @property
    def url(self) -> str:
        return _worker_service(self.token)

    def _kbs(self) -> ServiceKbs:
        return ServiceKbs(self.url, self.token)

    def create(self, name: str) -> None:
        self._kbs().create(name)

    def delete(self, name: str) -> None:
        self._kbs().delete(name)

    def delete_prefix(self, prefix: str) -> int:
        """Nothing to do from the driver: each worker's service is its own and goes with it."""
        return 0

    def wait_fitted(self, name: str, timeout: float = FIT_WAIT_S) -> float:
        return self._kbs().wait_fitted(name, timeout)

    def count_points(self, name: str) -> int:
        return self._kbs().count_points(name)

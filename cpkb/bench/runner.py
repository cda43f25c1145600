"""Run scenarios on a pool of worker processes, each in a fresh knowledge base.

The run function is a parameter (any picklable callable with `run_plan`'s signature), so the
pool, resumability and time limit work the same for the real planner and for small planners.
Workers are spawned (not forked: torch and PyBullet do not survive a fork well) and each
runs single-threaded BLAS, so `workers` processes use `workers` cores.
"""

from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import os
import re
import time
import traceback
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import TRANSFER_SAMPLER, Scenario
from server.lifeline import exit_with_parent

RunFn = Callable[..., Any]
"""`run_fn(task, method, seed, *, max_rollouts, kb_url, kb, quiet, **extra)` -> a result with
`to_json()` (dict or JSON text) or a mapping, holding at least `solved`, `rollouts`, `wall_s`.
With planner knobs set, `extra` has `config`: their dotted overrides (`planner.config`)."""

REQUIRED_FIELDS = ("solved", "rollouts", "wall_s")
KB_NAME_MAX = 64


class KbService(Protocol):
    """Where scenario knowledge bases live; picklable, since workers create and delete them."""

    url: str

    def create(self, name: str) -> None: ...

    def delete(self, name: str) -> None: ...

    def delete_prefix(self, prefix: str) -> int: ...

    def wait_fitted(self, name: str) -> float: ...


@dataclass(frozen=True)
class Job:
    """Everything a worker needs for one scenario (pickled to the worker)."""

    scenario: Scenario
    run_fn: RunFn
    kb_service: KbService | None
    kb_prefix: str
    max_rollouts: int
    predecessor_rollouts: int
    predecessor_kwargs: Mapping[str, Any] = field(default_factory=dict)
    config: Mapping[str, Any] = field(default_factory=dict)  # dotted planner overrides

    @property
    def kb_name(self) -> str:
        """Readable and unique within the bench; within the service's 64 safe characters."""
        s = self.scenario
        readable = re.sub(
            r"[^A-Za-z0-9_.-]", "_", f"{self.kb_prefix}-{s.task}-{s.method}-s{s.seed}"
        )
        if len(readable) <= KB_NAME_MAX:
            return readable
        digest = hashlib.sha1(f"{s.task}/{s.method}".encode()).hexdigest()[:12]
        return f"{self.kb_prefix}-{digest}-s{s.seed}"


@dataclass
class BenchOutcome:
    """How a bench call ended: counts of this call's runs, and whether time ran out."""

    finished: int = 0
    errors: int = 0
    remaining: int = 0
    skipped: int = 0
    timed_out: bool = False
    interrupted: bool = False
    error_messages: list[str] = field(default_factory=list)


def _as_dict(result: Any) -> dict[str, Any]:
    if hasattr(result, "to_json"):
        result = result.to_json()
    if isinstance(result, str | bytes):
        import json

        result = json.loads(result)
    if not isinstance(result, Mapping):
        raise TypeError(f"the run function returned {type(result).__name__}, not a result")
    out = dict(result)
    missing = [k for k in REQUIRED_FIELDS if k not in out]
    if missing:
        raise ValueError(f"the run result lacks {', '.join(missing)}")
    return out


def _call(job: Job, task: str, method: str, max_rollouts: int, **extra: Any) -> dict[str, Any]:
    kb_url = job.kb_service.url if job.kb_service is not None else None
    kb = job.kb_name if job.kb_service is not None else None
    if job.config:
        extra = {"config": dict(job.config), **extra}
    result = job.run_fn(
        task,
        method,
        job.scenario.seed,
        max_rollouts=max_rollouts,
        kb_url=kb_url,
        kb=kb,
        quiet=True,
        **extra,
    )
    return _as_dict(result)


def execute(job: Job) -> tuple[bool, dict[str, Any]]:
    """Run one scenario in its own knowledge base: (ok, result record or error record)."""
    s = job.scenario
    started = time.perf_counter()
    created = False
    try:
        if job.kb_service is not None:
            job.kb_service.create(job.kb_name)
            created = True
        predecessors = []
        for task in s.predecessors:
            pre = _call(
                job, task, TRANSFER_SAMPLER, job.predecessor_rollouts, **job.predecessor_kwargs
            )
            predecessors.append(
                {
                    k: pre.get(k)
                    for k in (
                        "solved",
                        "rollouts",
                        "rollouts_spent",
                        "wall_s",
                        "sim_s",
                        "kb_s",
                        "points_posted",
                    )
                }
                | {"task": task}
            )
        fit_wait_s = 0.0
        if predecessors and job.kb_service is not None:
            fit_wait_s = job.kb_service.wait_fitted(job.kb_name)
        record = _call(job, s.task, s.sampler, job.max_rollouts)
        record.pop("bindings_detail", None)
        record.update(
            task=s.task,
            method=s.method,
            sampler=s.sampler,
            seed=s.seed,
            max_rollouts=job.max_rollouts,
            predecessors=predecessors,
            predecessor_wall_s=sum(float(p["wall_s"] or 0.0) for p in predecessors),
            fit_wait_s=fit_wait_s,
            scenario_wall_s=time.perf_counter() - started,
            worker_pid=os.getpid(),
        )
        return True, record
    except Exception as exc:  # a failed run is reported and retried by a rerun, not fatal
        return False, {
            "task": s.task,
            "method": s.method,
            "seed": s.seed,
            "error": f"{type(exc).__name__}: {exc}",
            "traceback": traceback.format_exc(),
        }
    finally:
        if created and job.kb_service is not None:
            with contextlib.suppress(Exception):  # leftovers go by prefix at the end
                job.kb_service.delete(job.kb_name)


def _init_worker(bench_pid: int) -> None:
    """One BLAS/torch thread per worker: the pool, not the libraries, uses the cores. A worker
    also leaves when the bench process is gone (killed rather than interrupted, it cannot
    terminate its pool, and an orphaned worker would keep its run going for nothing)."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    exit_with_parent(bench_pid)


class Progress(Protocol):
    """What the runner reports to (a rich progress bar, or nothing)."""

    def start(self, total: int) -> None: ...

    def advance(self, ok: bool, record: Mapping[str, Any]) -> None: ...

    def stop(self) -> None: ...


class NoProgress:
    def start(self, total: int) -> None:
        pass

    def advance(self, ok: bool, record: Mapping[str, Any]) -> None:
        pass

    def stop(self) -> None:
        pass


def run_bench(
    scenarios: Sequence[Scenario],
    out_dir: Path | str,
    run_fn: RunFn,
    *,
    workers: int,
    max_rollouts: int,
    predecessor_rollouts: int = 30,
    predecessor_kwargs: Mapping[str, Any] | None = None,
    kb_service: KbService | None = None,
    time_limit_s: float | None = None,
    progress: Progress | None = None,
    config: Mapping[str, Any] | None = None,
) -> BenchOutcome:
    """Run the scenarios not yet finished in `out_dir`, appending each result as it lands.
    `config`: the planner's dotted overrides, for every run (predecessors too); pinned with the
    rollout caps, since results under other knobs are another variant.

    At the time limit (seconds from this call) the runs in flight are stopped and not
    recorded; a rerun with the same `out_dir` picks up exactly where this one stopped.
    """
    if workers < 1:
        raise ValueError("workers must be at least 1")
    store = ResultStore(out_dir)
    store.pin_config(
        {
            "max_rollouts": max_rollouts,
            "predecessor_rollouts": predecessor_rollouts,
            "config": dict(config or {}),
        }
    )
    pending = store.pending(list(scenarios))
    outcome = BenchOutcome(skipped=len(scenarios) - len(pending), remaining=len(pending))
    if not pending:
        return outcome
    prefix = f"bench-{uuid.uuid4().hex[:8]}"
    jobs = [
        Job(
            s,
            run_fn,
            kb_service,
            prefix,
            max_rollouts,
            predecessor_rollouts,
            dict(predecessor_kwargs or {}),
            dict(config or {}),
        )
        for s in pending
    ]
    deadline = None if time_limit_s is None else time.monotonic() + time_limit_s
    bar = progress or NoProgress()
    bar.start(len(jobs))
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(min(workers, len(jobs)), initializer=_init_worker, initargs=(os.getpid(),))
    results = pool.imap_unordered(execute, jobs, chunksize=1)
    try:
        for _ in range(len(jobs)):
            ok, record = _next_result(results, deadline)
            if ok:
                store.append_run(record)
                outcome.finished += 1
            else:
                store.append_error(record)
                outcome.errors += 1
                outcome.error_messages.append(
                    f"{record['task']} {record['method']} seed {record['seed']}: {record['error']}"
                )
            outcome.remaining -= 1
            bar.advance(ok, record)
        pool.close()
    except multiprocessing.TimeoutError:
        outcome.timed_out = True
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        pool.terminate()
        pool.join()
        bar.stop()
        if kb_service is not None and (outcome.timed_out or outcome.interrupted):
            # The service may be gone with the interrupt; nothing of value is in those KBs.
            with contextlib.suppress(Exception):
                kb_service.delete_prefix(prefix)
    return outcome


def _next_result(results: Any, deadline: float | None) -> tuple[bool, dict[str, Any]]:
    """The next finished run; polls so that the deadline and Ctrl-C are honoured."""
    while True:
        wait = 1.0 if deadline is None else min(1.0, deadline - time.monotonic())
        if wait <= 0:
            raise multiprocessing.TimeoutError
        try:
            return results.next(timeout=wait)
        except multiprocessing.TimeoutError:
            continue

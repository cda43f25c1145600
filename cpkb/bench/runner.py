"""Run scenarios on a pool of worker processes, each in a fresh knowledge base.

With `concurrent=N`, the runs of a cell go N at a time into one fresh knowledge base (seeds in
blocks of N, in the cell's seed order): the members of a group are dispatched one after the
other and wait for each other at a barrier, so that they plan at once and learn from each other
while they run; each record names its `group`. With `mixed`, a group holds different tasks of
one workspace instead (the bench's tasks in turn, seed by seed), as a lab's planners share one
base. When a group's last run is in, the points its base holds are counted against those its
runs posted (`groups.jsonl`): a point lost or stored twice shows there.

The run function is a parameter (any picklable callable with `run_plan`'s signature), so the
pool, resumability and time limit work the same for the real planner and for small planners.
Workers are spawned (not forked: torch and PyBullet do not survive a fork well) and each
runs single-threaded BLAS, so `workers` processes use `workers` cores.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import multiprocessing
import os
import re
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.managers import SyncManager
from pathlib import Path
from typing import Any, Protocol

from threadpoolctl import threadpool_limits

from cpkb.bench.clocks import clock_fields
from cpkb.bench.portfolio import Portfolio
from cpkb.bench.records import RunResult, as_record
from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import Scenario
from server.cpus import pin_process
from server.lifeline import exit_with_parent

RunFn = Callable[..., RunResult]
"""`run_fn(task, method, seed, *, max_rollouts, kb_url, kb, quiet, **extra)` -> a result with
`to_json()` or a mapping, holding at least `solved`, `rollouts`, `wall_s`.
With planner knobs set, `extra` has `config`: their dotted overrides (`planner.config`)."""

KB_NAME_MAX = 64
START_TOGETHER_S = 600.0  # the longest a group's run waits for the rest to start


def _kb_name(prefix: str, task: str, method: str, tail: str) -> str:
    """Readable and unique within the bench; within the service's 64 safe characters."""
    readable = re.sub(r"[^A-Za-z0-9_.-]", "_", f"{prefix}-{task}-{method}-{tail}")
    if len(readable) <= KB_NAME_MAX:
        return readable
    digest = hashlib.sha1(f"{task}/{method}".encode()).hexdigest()[:12]
    return f"{prefix}-{digest}-{tail}"


@dataclass(frozen=True)
class Group:
    """Runs of one cell planning at once on one knowledge base, created and deleted by the
    bench process; `barrier` (a manager's, shared by the workers) starts them together."""

    kb_name: str
    size: int
    barrier: Any
    mixed: bool = False


class KbService(Protocol):
    """Where scenario knowledge bases live; picklable, since workers create and delete them."""

    @property
    def url(self) -> str: ...

    def create(self, name: str) -> None: ...

    def delete(self, name: str) -> None: ...

    def delete_prefix(self, prefix: str) -> int: ...

    def wait_fitted(self, name: str) -> float: ...

    def count_points(self, name: str) -> int: ...


@dataclass(frozen=True)
class Job:
    """Everything a worker needs for one scenario (pickled to the worker)."""

    scenario: Scenario
    run_fn: RunFn
    kb_service: KbService | None
    kb_prefix: str
    max_rollouts: int
    predecessor_rollouts: int
    time_budget_s: float | None = None  # the target run's, in seconds (predecessors have none)
    predecessor_kwargs: Mapping[str, Any] = field(default_factory=dict)
    config: Mapping[str, Any] = field(default_factory=dict)  # dotted planner overrides
    group: Group | None = None
    # With `cores`, the run's cores: the planner takes the first, a portfolio of `trees`
    # trees one each (`cpkb.bench.portfolio`).
    cores: tuple[int, ...] = ()
    trees: int = 1

    @property
    def kb_name(self) -> str:
        if self.group is not None:
            return self.group.kb_name
        s = self.scenario
        return _kb_name(self.kb_prefix, s.task, s.method, f"s{s.seed}")


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


def _call(
    job: Job, task: str, method: str, max_rollouts: int, trees: int = 1, **extra: Any
) -> dict[str, Any]:
    kb_url = job.kb_service.url if job.kb_service is not None else None
    kb = job.kb_name if job.kb_service is not None else None
    config = {**job.config, **dict(job.scenario.overrides)}
    if config:
        extra = {"config": config, **extra}
    run_fn = Portfolio(job.run_fn, trees, job.cores[:trees]) if trees > 1 else job.run_fn
    result = run_fn(
        task,
        method,
        job.scenario.seed,
        max_rollouts=max_rollouts,
        kb_url=kb_url,
        kb=kb,
        quiet=True,
        **extra,
    )
    return as_record(result)


def execute(job: Job) -> tuple[bool, dict[str, Any]]:
    """Run one scenario in its own knowledge base: (ok, result record or error record)."""
    s = job.scenario
    started = time.perf_counter()
    created = False
    together = None
    if job.cores:
        pin_process(frozenset(job.cores[:1]))
    try:
        if job.group is not None:
            together = _start_together(job.group)
        elif job.kb_service is not None:
            job.kb_service.create(job.kb_name)
            created = True
        predecessors = []
        for task in s.predecessors:
            pre = _call(job, task, s.sampler, job.predecessor_rollouts, **job.predecessor_kwargs)
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
        budget = {} if job.time_budget_s is None else {"time_budget_s": job.time_budget_s}
        record = _call(job, s.task, s.sampler, job.max_rollouts, job.trees, **budget)
        record.pop("bindings_detail", None)
        record.update(
            task=s.task,
            method=s.method,
            sampler=s.sampler,
            base_method=s.runs,
            overrides=dict(s.overrides),
            seed=s.seed,
            max_rollouts=job.max_rollouts,
            time_budget_s=job.time_budget_s,
            predecessors=predecessors,
            predecessor_wall_s=sum(float(p["wall_s"] or 0.0) for p in predecessors),
            fit_wait_s=fit_wait_s,
            scenario_wall_s=time.perf_counter() - started,
            worker_pid=os.getpid(),
            cores=len(job.cores) or None,
        )
        record.update(clock_fields(record))
        if job.group is not None:
            record.update(
                group=job.group.kb_name,
                concurrent=job.group.size,
                mixed=job.group.mixed,
                started_together=together,
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


def _start_together(group: Group) -> bool:
    """Wait for the group's other runs; False if they did not all come (one failed to start):
    this run goes on alone rather than wait for ever."""
    try:
        group.barrier.wait(START_TOGETHER_S)
        return True
    except threading.BrokenBarrierError:
        return False


def _grouped(
    scenarios: Sequence[Scenario], pending: Sequence[Scenario], concurrent: int, mixed: bool
) -> list[list[Scenario]]:
    """The pending runs in groups of at most `concurrent` per cell (blocks of the cell's seeds
    among all `scenarios`, so that a rerun keeps the groups), in the order they come first.
    `mixed`: per method instead, in the scenarios' order (seed-major: each seed's tasks in
    turn), so that a group's runs are of different tasks."""
    block: dict[tuple[str, str, int], tuple[str, str, int]] = {}
    if mixed:
        by_method: dict[str, list[Scenario]] = {}
        for s in scenarios:
            by_method.setdefault(s.method, []).append(s)
        for method, members in by_method.items():
            for i, s in enumerate(members):
                block[s.key] = ("", method, i // concurrent)
    else:
        cells = itertools.groupby(sorted(scenarios), key=lambda s: (s.task, s.method))
        for (task, method), cell in cells:
            for i, s in enumerate(cell):
                block[s.key] = (task, method, i // concurrent)
    groups: dict[tuple[str, str, int], list[Scenario]] = {}
    for s in pending:
        groups.setdefault(block[s.key], []).append(s)
    return list(groups.values())


def _init_worker(bench_pid: int) -> None:
    """One BLAS/torch thread per worker: the pool, not the libraries, uses the cores. A worker
    also leaves when the bench process is gone (killed rather than interrupted, it cannot
    terminate its pool, and an orphaned worker would keep its run going for nothing)."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"  # for the libraries the run loads later
    threadpool_limits(limits=1)  # for those already loaded (numpy is), which read no variable
    exit_with_parent(bench_pid)


class RunPool(Protocol):
    """Where the jobs run: the local process pool, or a cluster's (`cpkb.bench.ray_pool`)."""

    def start(self, jobs: Sequence[Job]) -> None: ...

    def next_result(self, timeout: float) -> tuple[bool, dict[str, Any]] | None:
        """A finished job's `execute` answer, or None if none finished within `timeout`."""
        ...

    def stop(self) -> None:
        """Stop the jobs still running; their runs are redone by a rerun."""
        ...


class LocalPool:
    """`workers` spawned processes on this machine."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._pool: Any = None
        self._results: Any = None

    def start(self, jobs: Sequence[Job]) -> None:
        context = multiprocessing.get_context("spawn")
        size = min(self.workers, len(jobs))
        self._pool = context.Pool(size, initializer=_init_worker, initargs=(os.getpid(),))
        self._results = self._pool.imap_unordered(execute, jobs, chunksize=1)

    def next_result(self, timeout: float) -> tuple[bool, dict[str, Any]] | None:
        try:
            return self._results.next(timeout=timeout)
        except multiprocessing.TimeoutError:
            return None

    def stop(self) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()


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
    time_budget_s: float | None = None,
    predecessor_rollouts: int = 30,
    predecessor_kwargs: Mapping[str, Any] | None = None,
    kb_service: KbService | None = None,
    time_limit_s: float | None = None,
    progress: Progress | None = None,
    config: Mapping[str, Any] | None = None,
    concurrent: int = 1,
    mixed: bool = False,
    pool: RunPool | None = None,
    service: Mapping[str, Any] | None = None,
    cores: Sequence[int] = (),
    portfolio: Collection[str] = (),
) -> BenchOutcome:
    """Run the scenarios not yet finished in `out_dir`, appending each result as it lands.
    `config`: the planner's dotted overrides, for every run (predecessors too); pinned with the
    rollout caps, since results under other knobs are another variant; so is `service`, the
    embedded service's settings away from their defaults. `concurrent`: the runs
    of a cell N at a time on one knowledge base (pinned too; the pool has at least N workers);
    `mixed`: N runs of different tasks at a time instead (pinned).
    `pool`: where the runs go (default: a local pool of `workers` processes).
    `cores`: the cores each run gets (pinned; `cpkb bench --cores`): the planner runs on the
    first, and the methods in `portfolio` run as a portfolio of one tree per core.

    At the time limit (seconds from this call) the runs in flight are stopped and not
    recorded; a rerun with the same `out_dir` picks up exactly where this one stopped.
    """
    if workers < 1 or concurrent < 1:
        raise ValueError("workers and concurrent must be at least 1")
    transfer = sorted({s.method for s in scenarios if s.predecessors})
    if concurrent > 1 and transfer:
        raise ValueError(
            f"concurrent runs do not take predecessors: leave out {', '.join(transfer)}"
        )
    if concurrent > 1 and pool is not None:
        raise ValueError("concurrent runs wait for each other on this machine: use the local pool")
    if mixed and (concurrent < 2 or len({s.task for s in scenarios}) < 2):
        raise ValueError("mixed groups need --concurrent 2 or more and two tasks or more")
    store = ResultStore(out_dir)
    store.pin_config(
        {
            "max_rollouts": max_rollouts,
            "time_budget_s": time_budget_s,
            "predecessor_rollouts": predecessor_rollouts,
            "config": dict(config or {}),
            "concurrent": concurrent,
            "mixed": mixed,
            "service": dict(service or {}),
            "cores": len(cores) or None,
        }
    )
    pending = store.pending(list(scenarios))
    outcome = BenchOutcome(skipped=len(scenarios) - len(pending), remaining=len(pending))
    if not pending:
        return outcome
    if concurrent > 1 and kb_service is None:
        raise ValueError("concurrent runs share a knowledge base: they need a service")
    prefix = f"bench-{uuid.uuid4().hex[:8]}"
    context = multiprocessing.get_context("spawn")
    manager = None
    if concurrent > 1:
        manager = SyncManager(ctx=context)
        manager.start(_init_worker, (os.getpid(),))  # it too leaves with the bench process
    jobs: list[Job] = []
    open_groups: dict[tuple[str, str, int], Group] = {}
    grouped = _grouped(scenarios, pending, concurrent, mixed) if manager else None
    for members in grouped or [[s] for s in pending]:
        group = None
        if manager is not None:
            first = members[0]
            task = "mixed" if mixed else first.task
            name = _kb_name(prefix, task, first.method, f"g{first.seed}")
            group = Group(name, len(members), manager.Barrier(len(members)), mixed)
            open_groups.update({s.key: group for s in members})
        jobs += [
            Job(
                s,
                run_fn,
                kb_service,
                prefix,
                max_rollouts,
                predecessor_rollouts,
                time_budget_s,
                dict(predecessor_kwargs or {}),
                dict(config or {}),
                group,
                tuple(cores),
                len(cores) if cores and s.method in portfolio else 1,
            )
            for s in members
        ]
    deadline = None if time_limit_s is None else time.monotonic() + time_limit_s
    bar = progress or NoProgress()
    bar.start(len(jobs))
    pool = pool or LocalPool(max(workers, concurrent))
    pool.start(jobs)
    left = {g.kb_name: g.size for g in open_groups.values()}
    members_in: dict[str, list[Mapping[str, Any]]] = {name: [] for name in left}
    try:
        if kb_service is not None:
            for name in left:
                kb_service.create(name)
        for _ in range(len(jobs)):
            ok, record = _next_result(pool, deadline)
            done = open_groups.get((record["task"], record["method"], int(record["seed"])))
            if done is not None and kb_service is not None:
                left[done.kb_name] -= 1
                members_in[done.kb_name].append(record if ok else {})
                if not left[done.kb_name]:
                    _check_group(store, kb_service, done, members_in.pop(done.kb_name))
                    with contextlib.suppress(Exception):  # leftovers go by prefix at the end
                        kb_service.delete(done.kb_name)
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
    except multiprocessing.TimeoutError:
        outcome.timed_out = True
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        pool.stop()
        if manager is not None:
            manager.shutdown()
        bar.stop()
        leftovers = outcome.timed_out or outcome.interrupted or any(left.values())
        if kb_service is not None and leftovers:
            # The service may be gone with the interrupt; nothing of value is in those KBs.
            with contextlib.suppress(Exception):
                kb_service.delete_prefix(prefix)
    return outcome


def _check_group(
    store: ResultStore, kbs: KbService, group: Group, records: Sequence[Mapping[str, Any]]
) -> None:
    """Record the points the group's base holds against those its runs posted (only when every
    run finished: a failed run's posts are not known)."""
    if not all(records):
        return
    try:
        stored: int | None = kbs.count_points(group.kb_name)
    except Exception:  # the check is a record, not a reason to stop the bench
        stored = None
    posted = sum(int(r.get("points_posted") or 0) for r in records)
    store.append_group(
        {
            "group": group.kb_name,
            "size": group.size,
            "mixed": group.mixed,
            "runs": [f"{r['task']}:{r['seed']}" for r in records],
            "points_posted": posted,
            "points_stored": stored,
            "kb_error_runs": sum(1 for r in records if r.get("kb_errors")),
        }
    )


def _next_result(pool: RunPool, deadline: float | None) -> tuple[bool, dict[str, Any]]:
    """The next finished run; polls so that the deadline and Ctrl-C are honoured."""
    while True:
        wait = 1.0 if deadline is None else min(1.0, deadline - time.monotonic())
        if wait <= 0:
            raise multiprocessing.TimeoutError
        result = pool.next_result(wait)
        if result is not None:
            return result

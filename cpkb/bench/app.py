"""`cpkb bench` end to end: check the request, bring up the knowledge base, run, summarise."""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from rich.console import Console

from cpkb.bench.kbs import ServiceKbs
from cpkb.bench.plots import write_plots
from cpkb.bench.progress import RichProgress
from cpkb.bench.results import ResultStore
from cpkb.bench.runner import BenchOutcome, KbService, RunFn, run_bench
from cpkb.bench.scenarios import (
    BASELINE_METHOD,
    PAPER_BASELINE_METHOD,
    TRANSFER_METHODS,
    expand,
    method_run,
    predecessors,
    task_kinds,
)
from cpkb.bench.stats import (
    headers,
    notes,
    summarize,
    summarize_by_kind,
    table_rows,
    write_summary,
)
from cpkb.bench.together import HEADERS as TOGETHER_HEADERS
from cpkb.bench.together import GroupCheck, summarize_together, write_together
from cpkb.bench.together import table_rows as together_rows
from cpkb.bench.variants import Variant
from cpkb.cli.tables import whole_names_table
from server.cpus import format_cpu_list
from server.settings import surrogate_overrides

if TYPE_CHECKING:
    from planner.result import PlanResult


@dataclass(frozen=True)
class BenchSettings:
    tasks: Sequence[str]
    methods: Sequence[str]
    seeds: Sequence[int]
    workers: int
    out_dir: str | Path
    kb_url: str | None = None
    token: str | None = None
    suggest_in: str = "planner"
    max_rollouts: int = 2000
    time_budget_s: float | None = None  # a target run's budget in seconds, beside max_rollouts
    predecessor_rollouts: int = 30
    time_limit_s: float | None = None
    summary_only: bool = False
    quiet: bool = False
    config: Mapping[str, Any] = field(default_factory=dict)  # dotted planner overrides
    concurrent: int = 1  # the runs of a cell N at a time on one knowledge base
    mixed: bool = False  # N runs of different tasks at a time instead
    alone_dir: str | Path | None = None  # the same seeds run alone (default: OUT/alone)
    variants: Mapping[str, Variant] = field(default_factory=dict)  # named method + knobs
    ray_address: str | None = None  # run on this Ray cluster rather than a local pool
    # The embedded service on the cores the workers leave (`spare`, where there are any) or on
    # any core at a lower priority (`shared`).
    service_cores: Literal["spare", "shared"] = "spare"
    # Every method gets this many cores in all (`--cores`): a guided method's planner one and
    # its embedded service the others (or the planner's, with one); a method without knowledge
    # runs that many trees at once (`cpkb.bench.portfolio`). None: the cores are not counted.
    cores: int | None = None


def plan_run(
    task: str, method: str, seed: int, config: Mapping[str, Any] | None = None, **kwargs: Any
) -> PlanResult:
    """The real planner run (the bench's default run function);
    `config`: the dotted overrides of the planner's knobs."""
    from planner.config import PlanConfig
    from planner.run import run_plan

    return run_plan(task, method, seed, config=PlanConfig().with_overrides(config or {}), **kwargs)


def alone_dir(settings: BenchSettings) -> Path:
    """Where the same seeds run alone, for a `--concurrent` bench's comparison."""
    return Path(settings.alone_dir or Path(settings.out_dir) / "alone")


def known_methods() -> set[str]:
    import planner.search.samplers as samplers

    return set(samplers.methods()) | set(TRANSFER_METHODS)


def known_tasks() -> set[str]:
    from planner.tasks import list_tasks

    return {task.name for task in list_tasks()}


ANALYTIC_PREFIX = "analytic:"


def _is_task_file(task: str) -> bool:
    return "/" in task or task.endswith((".yaml", ".yml"))


def run_cores(cores: int) -> tuple[int, ...]:
    """The cores of a `--cores` run: the first `cores` this process may use."""
    allowed = sorted(os.sched_getaffinity(0))
    if cores > len(allowed):
        raise ValueError(f"--cores {cores}: this bench may use only {len(allowed)} cores")
    return tuple(allowed[:cores])


def service_env(cores: Sequence[int]) -> dict[str, str]:
    """Where a `--cores` run's embedded service runs: on the cores its planner leaves, or on
    the planner's own core when it has only one (the service counts among the run's cores)."""
    return {"CPKB_CPU_CORES": format_cpu_list(set(cores[1:] or cores))}


def portfolio_methods(settings: BenchSettings) -> set[str]:
    """The methods that run as a portfolio on `--cores`: those that use no knowledge base."""
    from planner.search.samplers import uses_knowledge

    runs = {method: method_run(method, settings.variants) for method in settings.methods}
    samplers = {method: TRANSFER_METHODS.get(run, run) for method, run in runs.items()}
    return {method for method, sampler in samplers.items() if not uses_knowledge(sampler)}


def _check_cores(settings: BenchSettings) -> None:
    """`--cores` counts every core a run uses: one run at a time, the bench's own service."""
    if settings.cores is None:
        return
    if settings.workers != 1:
        raise ValueError("--cores N gives one run N cores at a time: use --workers 1")
    if settings.kb_url is not None or settings.ray_address is not None:
        raise ValueError("--cores counts the embedded service's cores: not with --kb-url or --ray")
    if settings.concurrent > 1:
        raise ValueError("--cores gives one run its cores: not with --concurrent")
    if settings.service_cores != "spare":
        raise ValueError("--cores places the service itself: not with --service-cores shared")
    if not hasattr(os, "sched_getaffinity"):
        raise ValueError("--cores pins processes to cores, which this platform cannot")
    run_cores(settings.cores)


def check_request(settings: BenchSettings) -> None:
    """Name the unknown task or method before any worker starts."""
    _check_cores(settings)
    if settings.ray_address is not None:
        from cpkb.bench.ray_pool import require_ray

        require_ray()
        if settings.concurrent > 1:
            raise ValueError("--concurrent runs wait for each other on one machine: not with --ray")
    if settings.mixed:
        _check_mixed(settings)
    methods, tasks = known_methods() | set(settings.variants), known_tasks()
    unknown_m = [m for m in settings.methods if m not in methods]
    if unknown_m:
        raise ValueError(f"unknown method {unknown_m[0]!r} (known: {', '.join(sorted(methods))})")
    needed = set(settings.tasks)
    if any(method_run(m, settings.variants) in TRANSFER_METHODS for m in settings.methods):
        needed |= {p for t in settings.tasks for p in predecessors(t)}
    missing_files = [t for t in needed if _is_task_file(t) and not Path(t).is_file()]
    if missing_files:
        raise ValueError(f"no such task file: {missing_files[0]}")
    for task in sorted(t for t in needed if t.startswith(ANALYTIC_PREFIX)):
        from planner.search.analytic import analytic_world

        analytic_world(task.removeprefix(ANALYTIC_PREFIX))  # a ValueError names the known ones
    unknown_t = sorted(
        t for t in needed - tasks if not _is_task_file(t) and not t.startswith(ANALYTIC_PREFIX)
    )
    if unknown_t:
        raise ValueError(f"unknown task {unknown_t[0]!r} (known: {', '.join(sorted(tasks))})")


def _check_mixed(settings: BenchSettings) -> None:
    """Mixed groups are different tasks of one workspace, at least two at a time."""
    if settings.concurrent < 2 or len(settings.tasks) < 2:
        raise ValueError("--mixed needs --concurrent 2 or more and two tasks or more")
    from planner.tasks import load_task

    workspaces = {}
    for task in settings.tasks:
        if not task.startswith(ANALYTIC_PREFIX):
            workspaces[task] = load_task(task).workspace.name
    if len(set(workspaces.values())) > 1:
        shown = ", ".join(f"{t}: {w}" for t, w in workspaces.items())
        raise ValueError(f"--mixed runs tasks of one workspace together, not {shown}")


@contextlib.contextmanager
def knowledge_service(
    kb_url: str | None,
    token: str | None,
    planner_cores: int = 0,
    env: Mapping[str, str] | None = None,
) -> Iterator[ServiceKbs]:
    """The shared service if given; else one embedded service on a temporary SQLite file for
    the whole bench (each scenario still gets its own knowledge base, deleted after it), off
    the first `planner_cores` cores (`cpkb.embedded.embedded_service`); `env`: its
    environment's additions (`service_env`)."""
    if kb_url is not None:
        from client import CpkbClient, CpkbError

        try:
            with CpkbClient(kb_url, token=token, retries=1) as client:
                client.health()
        except CpkbError as exc:
            raise ValueError(f"no usable cpkb service at {kb_url}: {exc}") from None
        yield ServiceKbs(kb_url, token)
        return
    from cpkb.embedded import EmbeddedServiceError, embedded_service

    with tempfile.TemporaryDirectory(prefix="cpkb-bench-") as tmp, contextlib.ExitStack() as stack:
        try:
            url = stack.enter_context(
                embedded_service(
                    f"sqlite:///{Path(tmp) / 'bench.db'}",
                    planner_cores=planner_cores,
                    env=dict(env or {}),
                )
            )
        except EmbeddedServiceError as exc:
            raise ValueError(str(exc)) from None
        yield ServiceKbs(url, token)  # the embedded service reads CPKB_TOKEN too


def report(out_dir: str | Path, settings: BenchSettings, console: Console) -> None:
    """Rebuild the summary table and plots from everything in `out_dir`."""
    records = ResultStore(out_dir).records()
    kinds = task_kinds({r["task"] for r in records})
    methods = {r["method"] for r in records}
    # Against the strongest baseline; against the paper's too where it ran (its figures).
    paths: list[Path] = []
    for baseline, suffix in ((BASELINE_METHOD, ""), (PAPER_BASELINE_METHOD, "_paper")):
        if suffix and baseline not in methods:
            continue
        rows = summarize(records, settings.tasks, settings.methods, baseline)
        paths += write_summary(rows, out_dir, f"summary{suffix}", baseline)
        if len(kinds) > len(set(kinds.values())):
            by_kind = summarize_by_kind(records, kinds, settings.methods, baseline)
            paths += write_summary(by_kind, out_dir, f"summary_by_kind{suffix}", baseline)
        if not suffix:
            title = f"cpkb bench: {len(records)} runs in {out_dir}"
            console.print(whole_names_table(headers(baseline), table_rows(rows), title, names=2))
            console.print(notes(baseline))
    paths += write_plots(records, out_dir, settings.tasks, settings.methods)
    if settings.concurrent > 1:
        paths += _report_together(records, settings, console)
    console.print("wrote " + ", ".join(str(p) for p in paths))
    troubled = sum(r.kb_error_runs for r in rows)
    if troubled:
        console.print(
            f"[yellow]warning[/yellow]: {troubled} runs met knowledge-base errors (their "
            "samplers fell back to quasi-random there); see `notes` in runs.jsonl"
        )


def _report_together(
    records: Sequence[dict[str, Any]], settings: BenchSettings, console: Console
) -> list[Path]:
    """The concurrent runs against the same seeds alone, and the groups' point check."""
    alone = ResultStore(alone_dir(settings)).records()
    rows = summarize_together(records, alone, settings.tasks, settings.methods)
    check = GroupCheck.of(ResultStore(settings.out_dir).groups())
    title = f"together against alone ({alone_dir(settings)})"
    console.print(whole_names_table(TOGETHER_HEADERS, together_rows(rows), title))
    console.print(check.line())
    return write_together(rows, check, settings.out_dir)


def execute_bench(settings: BenchSettings, run_fn: RunFn, console: Console) -> BenchOutcome:
    """The bench's runs; a `--concurrent` bench runs the same seeds alone first (those not yet
    in the alone directory), for its comparison. An alone directory that holds them all is
    only read, whatever knobs it was run with: an A/B of a knob that matters only together
    (live sharing) compares both arms with the same alone runs."""
    if settings.concurrent <= 1:
        return _execute(settings, run_fn, console)
    solo = replace(settings, concurrent=1, mixed=False, out_dir=alone_dir(settings))
    started = time.monotonic()
    scenarios = expand(settings.tasks, settings.methods, settings.seeds, settings.variants)
    if not ResultStore(solo.out_dir).pending(scenarios):
        return _execute(settings, run_fn, console)
    first = _execute(solo, run_fn, console)
    if first.remaining or first.interrupted:
        return first
    left = None
    if settings.time_limit_s is not None:
        left = max(settings.time_limit_s - (time.monotonic() - started), 1.0)
    second = _execute(replace(settings, time_limit_s=left), run_fn, console)
    return BenchOutcome(
        finished=first.finished + second.finished,
        errors=first.errors + second.errors,
        remaining=second.remaining,
        skipped=first.skipped + second.skipped,
        timed_out=second.timed_out,
        interrupted=second.interrupted,
        error_messages=first.error_messages + second.error_messages,
    )


def _execute(settings: BenchSettings, run_fn: RunFn, console: Console) -> BenchOutcome:
    scenarios = expand(settings.tasks, settings.methods, settings.seeds, settings.variants)
    everything_done = not ResultStore(settings.out_dir).pending(scenarios)
    spare = settings.service_cores == "spare"
    cores = run_cores(settings.cores) if settings.cores is not None else ()
    service: contextlib.AbstractContextManager[KbService | None] = (
        contextlib.nullcontext(None)
        if everything_done  # no service to start just to skip every run
        else knowledge_service(
            settings.kb_url,
            settings.token,
            settings.workers if spare else 0,
            service_env(cores) if cores else None,
        )
    )
    pool = None
    embedded = settings.kb_url is None and settings.ray_address is None
    # What the embedded service ran with, pinned with the results: its settings away from their
    # defaults, and where it ran when not on shared cores.
    embedded_settings = surrogate_overrides() | (
        {"cpu_cores": "spare"} if spare and not cores else {}  # `--cores` is pinned apart
    )
    if settings.ray_address is not None:
        from cpkb.bench.ray_pool import RayPool, WorkerKbs

        pool = RayPool(settings.ray_address)
        if settings.kb_url is None and not everything_done:
            service = contextlib.nullcontext(WorkerKbs(settings.token))
    with service as kbs:
        return run_bench(
            scenarios,
            settings.out_dir,
            run_fn,
            workers=settings.workers,
            max_rollouts=settings.max_rollouts,
            time_budget_s=settings.time_budget_s,
            predecessor_rollouts=settings.predecessor_rollouts,
            predecessor_kwargs={"stop_at_first": False},
            kb_service=kbs,
            time_limit_s=settings.time_limit_s,
            progress=None if settings.quiet else RichProgress(console),
            config=settings.config,
            concurrent=settings.concurrent,
            mixed=settings.mixed,
            pool=pool,
            service=embedded_settings if embedded else {},
            cores=cores,
            portfolio=portfolio_methods(settings) if cores else (),
        )


def run_command(settings: BenchSettings, run_fn: RunFn | None = None) -> int:
    """The CLI's body; exit status 0 when every asked run has a result, 1 otherwise."""
    # Piped output (a log file, CI) gets the full table rather than 80 squeezed columns.
    console = Console(width=None if sys.stdout.isatty() else 200)
    if settings.summary_only:
        report(settings.out_dir, settings, console)
        return 0
    check_request(settings)
    if run_fn is None:
        options: dict[str, Any] = {"suggest_in": settings.suggest_in} | (
            {"token": settings.token} if settings.token is not None else {}
        )
        run_fn = functools.partial(plan_run, **options)
    outcome = execute_bench(settings, run_fn, console)
    console.print(
        f"{outcome.finished} runs finished, {outcome.skipped} already done, "
        f"{outcome.errors} failed, {outcome.remaining} left"
        + (" (time limit reached: rerun the same command to continue)" if outcome.timed_out else "")
        + (" (interrupted: rerun the same command to continue)" if outcome.interrupted else "")
    )
    for message in outcome.error_messages[:5]:
        console.print(f"[red]error[/red] {message}")
    if outcome.errors:
        console.print(f"tracebacks in {ResultStore(settings.out_dir).errors_path}")
    report(settings.out_dir, settings, console)
    return 0 if outcome.errors == 0 and outcome.remaining == 0 else 1

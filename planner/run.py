"""One binding search, composed: world + sampler + (for knowledge methods) the knowledge base.

`run_plan` is the single entry point of `cpkb plan`, `cpkb demo` and `cpkb bench`. A task is a
shipped task name, a task file, `analytic:<desk|deskP>` (the simulator-free worlds of
`planner.search.analytic`) or a ready `BindingWorld`. Methods that use the knowledge base reach
it at `kb_url`, or, with none given, in an embedded service on a temporary SQLite file.
"""

from __future__ import annotations

import contextlib
import os
import random
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from client.models import Value
from planner.search import PWUCT, SearchProgress
from planner.search import samplers as sampler_registry
from planner.world import BindingWorld

ANALYTIC_PREFIX = "analytic:"


@dataclass(frozen=True)
class Progress:
    rollouts: int
    max_rollouts: int
    best_depth: float
    solved: bool
    types_active: int
    types_activated: int
    elapsed_s: float


SUGGEST_IN = ("planner", "service")


@dataclass
class PlanResult:
    task: str
    method: str
    seed: int
    solved: bool
    rollouts: int
    rollouts_spent: int
    # wall_s: from loading the world to the search's end, the time to the binding, for every method
    wall_s: float
    sim_s: float
    kb_s: float
    sample_s: float
    bindings: dict[str, Value] | None
    best_depth: float
    types_activated: int = 0
    points_activated: int = 0
    types_active: int = 0
    points_posted: int = 0
    suggestions: int = 0
    local_suggestions: int = 0
    model_fetches: int = 0
    kb_errors: int = 0
    kb_parts: dict[str, float] = field(default_factory=dict)  # kb_s by what it waited for
    kb: str | None = None
    run: str | None = None
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """The `cpkb plan --json` dict."""
        out = asdict(self)
        for key in ("wall_s", "sim_s", "kb_s", "sample_s", "best_depth"):
            out[key] = round(out[key], 6)
        return out


def load_world(task: str | Path | BindingWorld, seed: int, *, gui: bool = False) -> BindingWorld:
    """A world for `task`; analytic worlds need no simulator."""
    if not isinstance(task, str | Path):
        return task
    name = str(task)
    if name.startswith(ANALYTIC_PREFIX):
        from planner.search.analytic import analytic_world

        return analytic_world(name.removeprefix(ANALYTIC_PREFIX))
    from planner import sim

    return sim.load_world(task, seed=seed, gui=gui)


def seed_everything(seed: int) -> None:
    """Python's, numpy's and torch's global generators, for anything outside our own rngs."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    try:
        import torch
    except ImportError:  # pragma: no cover - torch is a dependency; the guard keeps imports light
        return
    torch.manual_seed(seed)


@contextlib.contextmanager
def knowledge_service(kb_url: str | None, db_url: str | None = None) -> Iterator[str]:
    """`kb_url` as is, or an embedded service for this run on `db_url` (default: the service's
    own default database, CPKB_DATABASE_URL or ./cpkb.db, so knowledge persists across runs)."""
    if kb_url is not None:
        yield kb_url
        return
    from cpkb.embedded import embedded_service

    with embedded_service(db_url) as url:
        yield url


def run_plan(
    task: str | Path | BindingWorld,
    method: str,
    seed: int,
    *,
    max_rollouts: int = 2000,
    kb_url: str | None = None,
    kb: str = "default",
    token: str | None = None,
    stop_at_first: bool = True,
    quiet: bool = True,
    progress: Callable[[Progress], None] | None = None,
    gui: bool = False,
    worker: str | None = None,
    db_url: str | None = None,
    suggest_in: str = "planner",
) -> PlanResult:
    """Search bindings for `task` with `method` until the first feasible binding list (or, with
    `stop_at_first=False`, through the whole budget). `quiet=False` with no `progress` callback
    draws a progress line on stderr. `suggest_in`: where MPF is maximised, in this process from
    the service's model snapshots (`planner`) or by the service (`service`, which also pushes
    concurrent planners of one knowledge base apart)."""
    if method not in sampler_registry.methods():
        raise ValueError(
            f"unknown method {method!r}; known: {', '.join(sampler_registry.methods())}"
        )
    if max_rollouts < 1:
        raise ValueError("max_rollouts must be at least 1")
    if suggest_in not in SUGGEST_IN:
        raise ValueError(f"suggest_in must be one of {', '.join(SUGGEST_IN)}, not {suggest_in!r}")
    options = {
        "max_rollouts": max_rollouts,
        "kb_url": kb_url,
        "kb": kb,
        "token": token,
        "stop_at_first": stop_at_first,
        "gui": gui,
        "worker": worker,
        "db_url": db_url,
        "suggest_in": suggest_in,
    }
    if not quiet and progress is None:
        from planner.display import live_progress

        label = f"{getattr(task, 'name', task)} {method}"
        with live_progress(label, max_rollouts) as shown:
            return _plan(task, method, seed, progress=shown, **options)
    return _plan(task, method, seed, progress=progress, **options)


def _plan(
    task: str | Path | BindingWorld,
    method: str,
    seed: int,
    *,
    max_rollouts: int,
    kb_url: str | None,
    kb: str,
    token: str | None,
    stop_at_first: bool,
    progress: Callable[[Progress], None] | None,
    gui: bool,
    worker: str | None,
    db_url: str | None,
    suggest_in: str,
) -> PlanResult:
    seed_everything(seed)
    started = time.perf_counter()
    world = load_world(task, seed, gui=gui)
    try:
        if not sampler_registry.uses_knowledge(method):
            sampler = sampler_registry.make(method, seed=seed, world=world)
            try:
                return _search(
                    world,
                    method,
                    seed,
                    sampler,
                    None,
                    started,
                    max_rollouts,
                    stop_at_first,
                    progress,
                )
            finally:
                sampler.close()
        return _plan_with_knowledge(
            world,
            method,
            seed,
            started,
            max_rollouts,
            stop_at_first,
            progress,
            kb_url=kb_url,
            kb=kb,
            token=token,
            worker=worker,
            db_url=db_url,
            suggest_in=suggest_in,
        )
    finally:
        if world is not task:
            close = getattr(world, "close", None)
            if close is not None:
                close()


def _plan_with_knowledge(
    world: BindingWorld,
    method: str,
    seed: int,
    started: float,
    max_rollouts: int,
    stop_at_first: bool,
    progress: Callable[[Progress], None] | None,
    *,
    kb_url: str | None,
    kb: str,
    token: str | None,
    worker: str | None,
    db_url: str | None,
    suggest_in: str,
) -> PlanResult:
    from client import CpkbClient
    from planner.knowledge import KnowledgeSession

    with knowledge_service(kb_url, db_url) as url, CpkbClient(url, token=token) as client:
        client.create_kb(kb, exist_ok=True)
        session = KnowledgeSession(
            client,
            kb,
            world,
            worker=worker or f"{socket.gethostname()}:{os.getpid()}",
            local=suggest_in == "planner",
        )
        sampler = sampler_registry.make(method, seed=seed, world=world, knowledge=session)
        try:
            session.prematch()
            result = _search(
                world,
                method,
                seed,
                sampler,
                session,
                started,
                max_rollouts,
                stop_at_first,
                progress,
            )
        finally:
            sampler.close()
            session.close()
        stats = session.stats
        result.kb_s = stats.kb_s
        result.kb_parts = {part: round(s, 6) for part, s in sorted(stats.kb_parts.items())}
        result.types_activated = stats.types_activated
        result.points_activated = stats.points_activated
        result.types_active = stats.types_active
        result.points_posted = session.points_posted
        result.suggestions = stats.suggestions
        result.local_suggestions = stats.local_suggestions
        result.model_fetches = stats.model_fetches
        result.kb_errors = stats.errors + session.poster.failed
        result.kb = kb
        result.run = session.run
        result.notes.extend(f"{message} (x{n})" for message, n in stats.events.items())
        return result


def _search(
    world: BindingWorld,
    method: str,
    seed: int,
    sampler: Any,
    session: Any,
    started: float,
    max_rollouts: int,
    stop_at_first: bool,
    progress: Callable[[Progress], None] | None,
) -> PlanResult:
    def report(p: SearchProgress) -> None:
        if progress is None:
            return
        stats = session.stats if session is not None else None
        progress(
            Progress(
                rollouts=p.rollouts,
                max_rollouts=max_rollouts,
                best_depth=p.best_depth,
                solved=p.solved,
                types_active=stats.types_active if stats else 0,
                types_activated=stats.types_activated if stats else 0,
                elapsed_s=time.perf_counter() - started,
            )
        )

    search = PWUCT(world, sampler, seed=seed, observer=session)
    outcome = search.run(max_rollouts, stop_at_first=stop_at_first, progress=report)
    return PlanResult(
        task=world.name,
        method=method,
        seed=seed,
        solved=outcome.solved,
        rollouts=outcome.rollouts,
        rollouts_spent=outcome.rollouts_spent,
        wall_s=time.perf_counter() - started,
        sim_s=outcome.sim_s,
        kb_s=0.0,
        sample_s=outcome.sample_s,
        bindings=outcome.bindings,
        best_depth=outcome.best_depth,
        notes=["search space exhausted"] if outcome.exhausted else [],
    )

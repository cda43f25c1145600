"""One binding search, composed: world + sampler + (for knowledge methods) the knowledge base.

`run_plan` is the single entry point of `cpkb plan`, `cpkb demo` and `cpkb bench`; a `PlanRequest`
says what to run. A task is a shipped task name, a task file, `analytic:<desk|deskP>` (the
simulator-free worlds of `planner.search.analytic`) or a ready `BindingWorld`. Methods that use
the knowledge base reach it at `kb_url`: the command line hands in the URL of a service it
started (`cpkb.embedded`) when it was given none. Every knob of the run is in the request's
`PlanConfig`, recorded whole in its result.
"""

from __future__ import annotations

import os
import random
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.config import PlanConfig, method_config
from planner.result import PlanResult, Progress
from planner.search import PWUCT, SearchProgress, SearchResult
from planner.search import samplers as sampler_registry
from planner.world import BindingWorld

if TYPE_CHECKING:
    from planner.knowledge import KnowledgeClient, KnowledgeSession

ANALYTIC_PREFIX = "analytic:"


SUGGEST_IN = ("planner", "service")


@dataclass(frozen=True)
class PlanRequest:
    """One binding search: what to search, with which method and budget, where the knowledge
    base is, and the configuration. `config` is the method's effective one: a preset method's
    switches (`planner.config.PRESETS`) are applied to it on construction."""

    task: str | Path | BindingWorld
    method: str
    seed: int
    max_rollouts: int = 2000
    # Wall-clock seconds from the run's start (loading the world) after which no rollout starts:
    # a budget in time beside the one in rollouts, whichever ends first.
    time_budget_s: float | None = None
    stop_at_first: bool = True
    kb_url: str | None = None
    kb: str = "default"
    token: str | None = None
    worker: str | None = None
    suggest_in: str = "planner"
    gui: bool = False
    config: PlanConfig = field(default_factory=PlanConfig)

    def __post_init__(self) -> None:
        if self.method not in sampler_registry.methods():
            known = ", ".join(sampler_registry.methods())
            raise ValueError(f"unknown method {self.method!r}; known: {known}")
        if self.max_rollouts < 1:
            raise ValueError("max_rollouts must be at least 1")
        if self.time_budget_s is not None and not self.time_budget_s > 0:
            raise ValueError("time_budget_s must be above zero")
        if self.suggest_in not in SUGGEST_IN:
            raise ValueError(
                f"suggest_in must be one of {', '.join(SUGGEST_IN)}, not {self.suggest_in!r}"
            )
        object.__setattr__(self, "config", method_config(self.method, self.config))

    @property
    def label(self) -> str:
        return f"{getattr(self.task, 'name', self.task)} {self.method}"

    def knowledge_session(self, client: KnowledgeClient, world: BindingWorld) -> KnowledgeSession:
        """This run's session on its knowledge base for `world` (a goal-only task opens one per
        skeleton it searches)."""
        from planner.knowledge import KnowledgeSession

        return KnowledgeSession(
            client,
            self.kb,
            world,
            worker=self.worker or f"{socket.gethostname()}:{os.getpid()}",
            lookahead=self.config.cp_bo.lookahead,
            local=self.suggest_in == "planner",
            config=self.config.knowledge,
        )


def load_world(task: str | Path | BindingWorld, seed: int, *, gui: bool = False) -> BindingWorld:
    """A world for `task`; analytic worlds need no simulator."""
    if not isinstance(task, str | Path):
        return task
    name = str(task)
    if name.startswith(ANALYTIC_PREFIX):
        from planner.search.analytic import analytic_world

        return analytic_world(name.removeprefix(ANALYTIC_PREFIX))
    from planner import sim as simulator

    return simulator.load_world(task, seed=seed, gui=gui)


def seed_everything(seed: int) -> None:
    """Python's, numpy's and torch's global generators, for anything outside our own rngs."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    try:
        import torch
    except ImportError:  # pragma: no cover - torch is a dependency; the guard keeps imports light
        return
    torch.manual_seed(seed)


def run_plan(
    task: PlanRequest | str | Path | BindingWorld,
    method: str | None = None,
    seed: int | None = None,
    *,
    quiet: bool = True,
    progress: Callable[[Progress], None] | None = None,
    **options: Any,
) -> PlanResult:
    """Search bindings until the first feasible binding list (or, with `stop_at_first=False`,
    through the whole budget). Takes a `PlanRequest`, or its fields (`run_plan("desk", "cp-bo",
    0, max_rollouts=100)`). `quiet=False` with no `progress` callback draws a progress line on
    stderr. `suggest_in`: where MPF is maximised, in this process from the service's model
    snapshots (`planner`) or by the service (`service`, which also pushes concurrent planners of
    one knowledge base apart)."""
    if isinstance(task, PlanRequest):
        if method is not None or seed is not None or options:
            raise TypeError("give a PlanRequest or its fields, not both")
        request = task
    else:
        if method is None or seed is None:
            raise TypeError("run_plan needs a method and a seed")
        request = PlanRequest(task, method, seed, **options)
    if not quiet and progress is None:
        from planner.display import live_progress

        with live_progress(request.label, request.max_rollouts) as shown:
            return _plan(request, shown)
    return _plan(request, progress)


def _goal_only(task: str | Path | BindingWorld) -> Any:
    """The task, when it is a task file or shipped task posed by its goal alone; else None."""
    if not isinstance(task, str | Path) or str(task).startswith(ANALYTIC_PREFIX):
        return None
    from planner.tasks import load_task

    loaded = load_task(task)
    return loaded if not loaded.layers else None


def _plan(request: PlanRequest, progress: Callable[[Progress], None] | None) -> PlanResult:
    seed_everything(request.seed)
    started = time.perf_counter()
    goal_only = _goal_only(request.task)
    if goal_only is not None:
        from planner.goals.search import plan_goal

        return plan_goal(request, goal_only, started, progress)
    world = load_world(request.task, request.seed, gui=request.gui)
    try:
        if sampler_registry.uses_knowledge(request.method):
            return _plan_with_knowledge(request, world, started, progress)
        sampler = sampler_registry.make(
            request.method, seed=request.seed, world=world, config=request.config
        )
        try:
            return _search(request, world, sampler, None, started, progress)
        finally:
            sampler.close()
    finally:
        if world is not request.task:
            close = getattr(world, "close", None)
            if close is not None:
                close()


def _plan_with_knowledge(
    request: PlanRequest,
    world: BindingWorld,
    started: float,
    progress: Callable[[Progress], None] | None,
) -> PlanResult:
    from client import CpkbClient

    config = request.config
    if request.kb_url is None:
        raise ValueError(f"{request.method} needs a knowledge base: give kb_url")
    with CpkbClient(request.kb_url, token=request.token) as client:
        client.create_kb(request.kb, exist_ok=True)
        session = request.knowledge_session(client, world)
        sampler = sampler_registry.make(
            request.method, seed=request.seed, world=world, knowledge=session, config=config
        )
        try:
            if config.cp_bo.prematch:
                session.prematch()
            result = _search(request, world, sampler, session, started, progress)
            if result.bindings is not None:
                session.add_found(result.bindings, result.rollouts)
        finally:
            sampler.close()
            session.close()
        stats = session.stats
        return replace(
            result,
            knowledge=stats,
            kb=request.kb,
            run=session.run,
            notes=[*result.notes, *(f"{message} (x{n})" for message, n in stats.events.items())],
        )


def _search(
    request: PlanRequest,
    world: BindingWorld,
    sampler: Any,
    session: Any,
    started: float,
    progress: Callable[[Progress], None] | None,
) -> PlanResult:
    def report(p: SearchProgress) -> None:
        if progress is None:
            return
        stats = session.stats if session is not None else None
        progress(
            Progress(
                rollouts=p.rollouts,
                max_rollouts=request.max_rollouts,
                best_depth=p.best_depth,
                solved=p.solved,
                types_active=stats.types_active if stats else 0,
                types_activated=stats.types_activated if stats else 0,
                elapsed_s=time.perf_counter() - started,
            )
        )

    config = request.config.search
    search = PWUCT(world, sampler, seed=request.seed, config=config, observer=session)
    process_cpu, thread_cpu = time.process_time(), time.thread_time()
    deadline = None if request.time_budget_s is None else started + request.time_budget_s
    outcome = search.run(
        request.max_rollouts,
        stop_at_first=request.stop_at_first,
        progress=report,
        deadline=deadline,
    )
    background_cpu = (time.process_time() - process_cpu) - (time.thread_time() - thread_cpu)
    return PlanResult(
        task=world.name,
        method=request.method,
        seed=request.seed,
        solved=outcome.solved,
        rollouts=outcome.rollouts,
        rollouts_spent=outcome.rollouts_spent,
        wall_s=time.perf_counter() - started,
        sim_s=outcome.sim_s,
        sample_s=outcome.sample_s,
        bindings=outcome.bindings,
        best_depth=outcome.best_depth,
        time_budget_s=request.time_budget_s,
        timed_out=outcome.timed_out,
        notes=_notes(outcome),
        background_cpu_s=round(max(background_cpu, 0.0), 6),
        config=request.config.to_dict(),
    )


def _notes(outcome: SearchResult) -> list[str]:
    notes = ["search space exhausted"] if outcome.exhausted else []
    if outcome.timed_out:
        notes.append("time budget reached")
    if outcome.restarts:
        notes.append(f"tree restarted {outcome.restarts} times")
    return notes

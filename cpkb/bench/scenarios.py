"""What a bench runs: scenarios (task, method, seed) and the transfer predecessors.

Scenarios are ordered seed-major, so a bench cut short by its time limit leaves every
(task, method) cell with nearly the same number of seeds. A task's predecessors are the ones
its task file declares (`predecessors:`), for shipped tasks and task files alike.
"""

from __future__ import annotations

import argparse
import functools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from cpkb.bench.variants import Variant

TRANSFER_METHOD = "cp-bo-transfer"
"""Not a sampler: `cp-bo` on a knowledge base first filled by the task's predecessors."""

TRANSFER_METHODS: Mapping[str, str] = {
    TRANSFER_METHOD: "cp-bo",
    "cp-bo-paper-transfer": "cp-bo-paper",
}
"""Each transfer method and the method that runs its predecessors and then its target: the
paper's CP-BO Transfer is `cp-bo-paper-transfer`, the extended system's `cp-bo-transfer`."""

PAPER_METHODS = ("quasi-random", "mcts-bo", "cp-bo", TRANSFER_METHOD)
PAPER_TASKS = ("desk", "regrasp", "pack")
BASELINE_METHOD = "quasi-random-restarts"
"""The strongest search without learning, which every claim is made against."""
PAPER_BASELINE_METHOD = "quasi-random"
"""The paper's baseline (one tree, never restarted), for the comparison with its figures."""

ANALYTIC_PREFIX = "analytic:"

PAPER_REDUCTION_PERCENT: Mapping[str, float] = {"desk": 71.69, "regrasp": 60.37, "pack": 43.60}
"""CP-BO Transfer's relative reduction of mean rollouts against quasi-random (paper, sec. V)."""


@dataclass(frozen=True, order=True)
class Scenario:
    """One run of the bench: its own fresh knowledge base, one result line. A variant's
    scenario (`cpkb.bench.variants`) names the variant as its method, runs `base`, and adds
    its `overrides` to the bench's planner knobs."""

    task: str
    method: str
    seed: int
    base: str = ""
    overrides: tuple[tuple[str, Any], ...] = ()

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.task, self.method, self.seed)

    @property
    def runs(self) -> str:
        """The method this scenario runs: itself, or a variant's."""
        return self.base or self.method

    @property
    def predecessors(self) -> tuple[str, ...]:
        return predecessors(self.task) if self.runs in TRANSFER_METHODS else ()

    @property
    def sampler(self) -> str:
        """The planner method that searches the predecessors and the target task."""
        return TRANSFER_METHODS.get(self.runs, self.runs)


@functools.lru_cache(maxsize=256)
def predecessors(task: str) -> tuple[str, ...]:
    """The tasks `cp-bo-transfer` runs (with `cp-bo`) into the scenario's knowledge base before
    `task`, as its task file declares them (the shipped files: the paper's Fig. 4). An analytic
    world (`analytic:desk`, simulator-free) takes the predecessors of the shipped task of its
    name, each in its analytic form, so the whole bench can be exercised in seconds."""
    from planner.tasks import load_task
    from planner.tasks.loader import data_dir

    if task.startswith(ANALYTIC_PREFIX):
        name = task.removeprefix(ANALYTIC_PREFIX)
        if not (data_dir() / f"{name}.yaml").is_file():
            return ()  # no shipped namesake: the bench names the unknown analytic world
        return tuple(f"{ANALYTIC_PREFIX}{p}" for p in load_task(name).predecessors if "/" not in p)
    return load_task(task).predecessors


def task_kinds(tasks: Iterable[str]) -> dict[str, str]:
    """The declared `kind` of each task that has one (a generated suite's desk, regrasp and
    pack); tasks that cannot be loaded or declare none are left out."""
    from planner.tasks import load_task

    kinds = {}
    for task in tasks:
        if task.startswith(ANALYTIC_PREFIX):
            continue
        try:
            kind = load_task(task).kind
        except (ValueError, OSError):
            continue
        if kind:
            kinds[task] = kind
    return kinds


def method_run(method: str, variants: Mapping[str, Variant]) -> str:
    """The method that `method` runs: a variant's, or itself."""
    return variants[method].method if method in variants else method


def expand(
    tasks: Sequence[str],
    methods: Sequence[str],
    seeds: Iterable[int],
    variants: Mapping[str, Variant] | None = None,
) -> list[Scenario]:
    """Every (task, method, seed), seed-major; a method may be one of `variants`. A transfer
    method (or a variant of one) needs a task with predecessors."""
    variants = variants or {}
    transfer = [m for m in methods if method_run(m, variants) in TRANSFER_METHODS]
    for task in tasks:
        if transfer and not predecessors(task):
            raise ValueError(
                f"{transfer[0]} has no predecessor tasks for {task!r}: declare them in its "
                "task file (`predecessors: [deskP, ../other/task.yaml]`)"
            )
    return [
        Scenario(t, m, s, variants[m].method, variants[m].overrides)
        if m in variants
        else Scenario(t, m, s)
        for s in seeds
        for t in tasks
        for m in methods
    ]


def seed_range(text: str) -> range:
    """`8000-8004` (both ends included) or a single seed."""
    first, _, last = text.partition("-")
    try:
        low, high = int(first), int(last or first)
    except ValueError:
        raise argparse.ArgumentTypeError(f"seeds: {text!r} is not FIRST-LAST") from None
    if high < low:
        raise argparse.ArgumentTypeError(f"seeds: {text!r} ends before it starts")
    return range(low, high + 1)

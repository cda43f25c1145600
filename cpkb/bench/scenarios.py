"""What a bench runs: scenarios (task, method, seed) and the transfer predecessors.

Scenarios are ordered seed-major, so a bench cut short by its time limit leaves every
(task, method) cell with nearly the same number of seeds.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

TRANSFER_METHOD = "cp-bo-transfer"
"""Not a sampler: `cp-bo` on a knowledge base first filled by the task's predecessors."""

TRANSFER_SAMPLER = "cp-bo"

PAPER_METHODS = ("quasi-random", "mcts-bo", "cp-bo", TRANSFER_METHOD)
PAPER_TASKS = ("desk", "regrasp", "pack")
BASELINE_METHOD = "quasi-random"

PREDECESSORS: Mapping[str, tuple[str, ...]] = {
    "desk": ("deskP",),
    "regrasp": ("deskP", "desk"),
    "pack": ("packP1", "packP2", "packP3"),
}
"""The paper's Fig. 4: tasks run (with `cp-bo`) into the scenario's KB before the target."""

PAPER_REDUCTION_PERCENT: Mapping[str, float] = {"desk": 71.69, "regrasp": 60.37, "pack": 43.60}
"""CP-BO Transfer's relative reduction of mean rollouts against quasi-random (paper, sec. V)."""


@dataclass(frozen=True, order=True)
class Scenario:
    """One run of the bench: its own fresh knowledge base, one result line."""

    task: str
    method: str
    seed: int

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.task, self.method, self.seed)

    @property
    def predecessors(self) -> tuple[str, ...]:
        return predecessors(self.task) if self.method == TRANSFER_METHOD else ()

    @property
    def sampler(self) -> str:
        """The planner method that searches the target task."""
        return TRANSFER_SAMPLER if self.method == TRANSFER_METHOD else self.method


def predecessors(task: str) -> tuple[str, ...]:
    """Fig. 4's predecessors; `analytic:desk` (the planner's simulator-free world) has
    `analytic:deskP`, so the whole bench can be exercised in seconds."""
    prefix, _, name = task.rpartition(":")
    return tuple(f"{prefix}:{p}" if prefix else p for p in PREDECESSORS.get(name, ()))


def expand(tasks: Sequence[str], methods: Sequence[str], seeds: Iterable[int]) -> list[Scenario]:
    """Every (task, method, seed), seed-major; `cp-bo-transfer` needs a task with predecessors."""
    for task in tasks:
        if TRANSFER_METHOD in methods and not predecessors(task):
            known = ", ".join(sorted(PREDECESSORS))
            raise ValueError(
                f"{TRANSFER_METHOD} has no predecessor tasks for {task!r} (it knows: {known})"
            )
    return [Scenario(t, m, s) for s in seeds for t in tasks for m in methods]

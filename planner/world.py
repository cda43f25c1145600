"""The interface between the tree search and a simulator.

The search never imports PyBullet: it talks to a `BindingWorld`. The PyBullet world
(`planner.sim`) and the small analytic worlds of the tests both implement it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from client.models import Value
from planner.skeleton import OperatorCall, Skeleton


@dataclass(frozen=True)
class Culprit:
    """A body in collision, the one most in contact first; `depth` is penetration in metres (>0)."""

    body: str
    depth: float
    pose: tuple[float, ...] | None = None


PROGRESS_CAP = 0.999
"""The most a failed check's `detail["progress"]` (how far it got, in [0, 1)) may be: below one,
so a failure never scores like passing the check."""


@dataclass(frozen=True)
class CheckResult:
    """The verdict of one transition operator call."""

    call: OperatorCall
    ok: bool
    reason: str = ""
    culprits: tuple[Culprit, ...] = ()
    detail: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class TransitionOutcome:
    """All checks run for one transition layer, in order; on failure the last one failed."""

    checks: tuple[CheckResult, ...]
    state: object | None = None
    sim_seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    @property
    def failed(self) -> CheckResult | None:
        return next((c for c in self.checks if not c.ok), None)


class BindingWorld(Protocol):
    """A task to bind: its skeleton and a way to execute transition layers.

    `state` is opaque to the search: the world returns it with each successful transition
    and restores it before executing the next layer from that tree node.
    """

    name: str
    skeleton: Skeleton

    def initial_state(self) -> object: ...

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object
    ) -> TransitionOutcome:
        """Run transition layer `index` with every decision bound so far, from `state`."""
        ...

"""The interface between the tree search and a simulator.

The search never imports PyBullet: it talks to a `BindingWorld`. The PyBullet world
(`planner.sim`) and the small analytic worlds of the tests both implement it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from contract.models import Value
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
    conclusive: bool = True
    """Whether a failure proves the inputs infeasible. A check that searches with randomness (IK
    restarts, a sampling motion planner) and found nothing is inconclusive: another attempt at
    the same inputs, with other random draws, may pass."""


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

    @property
    def conclusive(self) -> bool:
        """A failure that another attempt at the same bindings cannot undo (see
        `CheckResult.conclusive`); a passed layer is conclusive too."""
        failed = self.failed
        return failed is None or failed.conclusive


Extents = tuple[float, float]


@dataclass(frozen=True)
class WorldGeometry:
    """What a world tells the encodings about its geometry (`planner.failures.graphs`), in
    metres; a world without geometry (an analytic one) tells nothing and gets the encodings of
    the declared domains. Tuples, not dicts: a geometry keys the process's cache of graphs.

    `body_sizes`: each movable body's box `(size_x, size_y, size_z)`; its footprint
    `(size_x, size_y)` gives the symmetries of its grasps. `arm`: the arm's URDF when it is not
    the Panda, so that failure graphs, and with them the knowledge learnt, are about one arm (the
    Panda's graphs name no arm, as before arms could be chosen, so knowledge stored then still
    matches)."""

    body_sizes: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    arm: str = ""

    def size(self, body: str) -> tuple[float, float, float] | None:
        return dict(self.body_sizes).get(body)

    def footprint(self, body: str) -> Extents | None:
        size = self.size(body)
        return (size[0], size[1]) if size is not None else None


class BindingWorld(Protocol):
    """A task to bind: its skeleton and a way to execute transition layers.

    `state` is opaque to the search: the world returns it with each successful transition
    and restores it before executing the next layer from that tree node. `geometry` is what it
    tells the encodings (`WorldGeometry()` for none). `culprit_candidates`: every body a failed
    check may name as its culprit (none for a world that names none).
    """

    name: str
    skeleton: Skeleton
    geometry: WorldGeometry
    culprit_candidates: tuple[str, ...]

    def initial_state(self) -> object: ...

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        """Run transition layer `index` with every decision bound so far, from `state`.
        `attempt` > 0 repeats bindings whose earlier attempts failed inconclusively: the world
        draws its random numbers afresh for it (attempt 0 draws as it always did)."""
        ...

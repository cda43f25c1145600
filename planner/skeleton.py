"""A task's skeleton: decision and transition layers of operator calls (Table I of the paper).

Pure data, shared by the world (which executes transitions) and the tree search (which
binds decisions and backtracks failures into causal graphs). Arguments starting with `#`
are variables produced by an earlier call; other arguments are workspace constants
(bodies, regions, `pose0`, `config0`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from contract.models import Domain

LayerKind = Literal["decision", "transition"]


@dataclass(frozen=True)
class OperatorCall:
    """`name(args...) -> outputs`, e.g. `Inv-kin(body, pose0, #dir1) -> #config1`."""

    name: str
    args: tuple[str, ...]
    outputs: tuple[str, ...] = ()


@dataclass(frozen=True)
class DecisionVar:
    """One open binding: `var` is task-local (`#dir2`), `kind` is task-independent (`#dir`)."""

    var: str
    kind: str
    domain: Domain
    producer: OperatorCall


@dataclass(frozen=True)
class Layer:
    kind: LayerKind
    calls: tuple[OperatorCall, ...]
    decision: DecisionVar | None = None


@dataclass(frozen=True)
class Skeleton:
    """Alternating decision and transition layers; decision layer i is followed by transition i."""

    layers: tuple[Layer, ...] = field(default_factory=tuple)

    @property
    def decisions(self) -> tuple[DecisionVar, ...]:
        return tuple(layer.decision for layer in self.layers if layer.decision is not None)

    @property
    def transitions(self) -> tuple[Layer, ...]:
        return tuple(layer for layer in self.layers if layer.kind == "transition")

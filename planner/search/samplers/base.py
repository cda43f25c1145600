"""The one interface every node-expansion sampler implements.

The tree calls `propose` when progressive widening opens a new child at a decision node. The
context carries what a sampler may use: the variable and its domain, the earlier bindings on
this path, the values of the existing children with their backed-up rewards, and the run's
seeded generator. A sampler must not return an existing child's value of a categorical variable.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from contract.models import Value
from planner.skeleton import DecisionVar


@dataclass(frozen=True)
class SampleContext:
    var: DecisionVar
    path: dict[str, Value]
    siblings: tuple[Value, ...]
    sibling_rewards: tuple[float, ...]
    sibling_visits: tuple[int, ...]
    depth: int
    rollout: int
    rng: np.random.Generator
    sibling_matrix: np.ndarray | None = None  # continuous siblings as an (n, dim) array
    # The children's backed-up rewards, graded within the failed check (`ChildNode.score`): they
    # differ between children that failed at one check; None from a tree that does not grade.
    sibling_scores: tuple[float, ...] | None = None


@dataclass(frozen=True)
class Proposal:
    """A value with the knowledge base's probability that it is feasible (its MPF). A node
    whose best proposal is unlikely to be feasible is *hopeless*: its parent widens as if it
    were a dead end (the tree still may come back to it, so completeness is kept)."""

    value: Value
    p_feasible: float


class Sampler(Protocol):
    name: str
    keeps_knowledge: bool
    """Whether what it learns outlives the tree (in a knowledge base). Only then does the tree
    restart (`SearchConfig.restart_unit`), unless `SearchConfig.restart_without_knowledge`
    says every sampler does: a fresh tree of a sampler that keeps nothing throws away every
    failure it has met, but draws its checks afresh (`quasi-random-restarts`)."""

    def propose(self, ctx: SampleContext) -> Value | Proposal:
        """A value for `ctx.var`, from its domain; never a sibling of a categorical variable."""
        ...

    def propose_untried(self, ctx: SampleContext) -> Proposal | None:
        """At a node that the PW law keeps from widening: the best untried value with its
        P(feasible), or None for a sampler without that view. The tree opens it when it beats
        every open child's outlook (`SearchConfig.outlook_ratio`)."""
        ...

    def chain(self) -> dict[str, Value] | None:
        """A complete binding to follow as the next rollout (one another planner's rollout
        passed), or None: the tree takes each of its values, opening the children it lacks."""
        ...

    def close(self) -> None:
        """Release whatever the sampler holds (connections, threads)."""
        ...

"""CP-BO: node expansion by the knowledge base's MPF suggestion.

At a decision node, the active types whose decision vertexes include this variable constrain the
suggestion: earlier decisions of the path are fixed, later ones are optimised jointly (the
session's lookahead), and the siblings are excluded. The answer's MPF goes to the tree with the
value (a `Proposal`), so a node the knowledge base has given up on lets its parent widen. Where
no type is active, or the service cannot answer, the node expands like the quasi-random baseline.

A looked-ahead answer is a whole continuation: the later decisions that make this value's MPF.
A node that the continuation leads to (a new child's decision, with the values above it) takes
its first value from it instead of asking, as long as its own constraints are among those the
answer weighed: a fresh descent costs one suggestion, not one per decision.

Each of these extensions of the paper's sampler has its switch in `CpBoConfig`; `cp-bo-paper`
(`planner.config.PRESETS`) is this sampler with all of them off.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from contract.models import CategoricalDomain, Constraint, SuggestedPoint, SuggestOut, Value
from planner.config import CpBoConfig, PlanConfig, QuasiRandomConfig
from planner.knowledge import KnowledgeSession
from planner.search.samplers.base import Proposal, SampleContext
from planner.search.samplers.quasi_random import space_filling

NodeKey = tuple[str, tuple[tuple[str, object], ...]]
Signature = tuple[tuple[str, tuple[tuple[str, str], ...]], ...]  # the node's (type, bind) pairs


@dataclass
class _Batch:
    constraints: Signature
    proposals: list[Proposal]
    rollout: int


@dataclass(frozen=True)
class _Continuation:
    """A later decision's value from an earlier node's looked-ahead answer."""

    weighed: frozenset[tuple[str, tuple[tuple[str, str], ...]]]  # the answer's constraints
    proposal: Proposal
    rollout: int


class CpBoSampler:
    name = "cp-bo"
    keeps_knowledge = True

    def __init__(
        self,
        knowledge: KnowledgeSession,
        config: CpBoConfig | None = None,
        fallback: QuasiRandomConfig | None = None,
    ) -> None:
        self.knowledge = knowledge
        self.config = config if config is not None else CpBoConfig()
        self.fallback = fallback if fallback is not None else QuasiRandomConfig()
        self.guided = 0
        self.unguided = 0
        self._batches: dict[NodeKey, _Batch] = {}
        self._continuations: dict[NodeKey, _Continuation] = {}
        self._order = [d.var for d in knowledge.skeleton.decisions]

    def propose(self, ctx: SampleContext) -> Value | Proposal:
        domain = ctx.var.domain
        if isinstance(domain, CategoricalDomain):
            left = [c for c in domain.choices if c not in ctx.siblings]
            if len(left) == 1:
                return left[0]
        batch = self._batch(ctx, self.config.batch_max_age)
        if batch is not None and batch.proposals:
            self.guided += 1
            return batch.proposals.pop(0)
        self.unguided += 1
        return space_filling(ctx, self.fallback.candidates_per_dim)

    def propose_untried(self, ctx: SampleContext) -> Proposal | None:
        """The next point of this node's batch, left in it: the best untried value the
        knowledge base knows of, for the price of a look."""
        batch = self._batch(ctx, self.config.outlook_max_age)
        return batch.proposals[0] if batch is not None and batch.proposals else None

    def chain(self) -> dict[str, Value] | None:
        return self.knowledge.next_chain()

    def _batch(self, ctx: SampleContext, max_age: int) -> _Batch | None:
        """This node's batch without the points since tried; asked anew when it is used up,
        older than `max_age` rollouts (`batch_max_age` for a value taken, `outlook_max_age` for
        a look), or the node's constraints changed (a type became active here or on the later
        decisions it looks ahead to: a batch that kept its points when only a later type was new
        would go on ignoring that type; BENCHMARKS.md has the measurement). None where no type
        is active or the service cannot answer."""
        constraints = self.knowledge.constraints_at(ctx.var.var, ctx.path)
        if not constraints:
            return None
        key = _node_key(ctx)
        signature = tuple((c.type_id, tuple(sorted(c.bind.items()))) for c in constraints)
        cached = self._batches.get(key)
        if cached is None:
            cached = self._continued(key, ctx, signature)
        if cached is not None:
            cached.proposals = [p for p in cached.proposals if _valid(p.value, ctx)]
        if (
            cached is None
            or cached.constraints != signature
            or not cached.proposals
            or ctx.rollout - cached.rollout > max_age
        ):
            cached = self._ask(ctx, constraints, signature)
            if cached is None:
                return None
            self._batches[key] = cached
        return cached

    def _ask(
        self,
        ctx: SampleContext,
        constraints: list[Constraint],
        signature: Signature,
    ) -> _Batch | None:
        seed = int(ctx.rng.integers(2**31 - 1))
        answer = self.knowledge.suggest(
            ctx.var, ctx.path, ctx.siblings, constraints, seed, n=self.config.batch
        )
        if answer is None:
            return None
        points: Sequence[SuggestedPoint | SuggestOut] = answer.batch or [answer]
        proposals = [
            Proposal(value, point.mpf)
            for point in points
            if (value := point.x.get(ctx.var.var)) is not None and _valid(value, ctx)
        ]
        if self.config.continuations:
            weighed = frozenset(signature)
            for point in points:
                self._remember_continuation(ctx, point.x, point.mpf, weighed)
        return _Batch(signature, proposals, ctx.rollout)

    def _remember_continuation(
        self, ctx: SampleContext, x: dict[str, Value], mpf: float, weighed: frozenset
    ) -> None:
        """Each later decision that `x` gives, down to the first it does not, for the node it
        would be decided at (the path extended by `x`'s values above it)."""
        if ctx.var.var not in x:
            return
        path = {**ctx.path, ctx.var.var: x[ctx.var.var]}
        for var in self._order[self._order.index(ctx.var.var) + 1 :]:
            if var not in x:
                return
            key = _key(var, path)
            if key not in self._batches and key not in self._continuations:
                self._continuations[key] = _Continuation(
                    weighed, Proposal(x[var], mpf), ctx.rollout
                )
            path[var] = x[var]

    def _continued(self, key: NodeKey, ctx: SampleContext, signature: Signature) -> _Batch | None:
        """A fresh node's first value from an earlier answer's continuation, if that answer
        weighed every constraint of this node and is recent enough."""
        continuation = self._continuations.pop(key, None)
        if (
            continuation is None
            or not set(signature) <= continuation.weighed
            or ctx.rollout - continuation.rollout > self.config.batch_max_age
        ):
            return None
        return _Batch(signature, [continuation.proposal], continuation.rollout)

    def close(self) -> None:
        self._batches.clear()
        self._continuations.clear()


def _node_key(ctx: SampleContext) -> NodeKey:
    return _key(ctx.var.var, ctx.path)


def _key(var: str, path: dict[str, Value]) -> NodeKey:
    return var, tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in path.items()))


def _valid(value: Value, ctx: SampleContext) -> bool:
    domain = ctx.var.domain
    if isinstance(domain, CategoricalDomain):
        return isinstance(value, str) and value in domain.choices and value not in ctx.siblings
    return (
        isinstance(value, list)
        and value not in ctx.siblings
        and len(value) == len(domain.low)
        and all(lo <= v <= hi for v, lo, hi in zip(value, domain.low, domain.high, strict=True))
    )


def factory(
    *, config: PlanConfig, knowledge: KnowledgeSession | None = None, **_: object
) -> CpBoSampler:
    if knowledge is None:
        raise ValueError("cp-bo needs a knowledge session")
    return CpBoSampler(knowledge, config.cp_bo, config.quasi_random)

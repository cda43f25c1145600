"""CP-BO: node expansion by the knowledge base's MPF suggestion.

At a decision node, the active types whose decision vertexes include this variable constrain the
suggestion: earlier decisions of the path are fixed, later ones are optimised jointly (the
session's lookahead), and the siblings are excluded. The answer's MPF goes to the tree with the
value (a `Proposal`), so a node the knowledge base has given up on lets its parent widen. Where
no type is active, or the service cannot answer, the node expands like the quasi-random baseline.
"""

from __future__ import annotations

from client.models import CategoricalDomain, Value
from planner.knowledge import KnowledgeSession
from planner.search.samplers import register
from planner.search.samplers.base import Proposal, SampleContext
from planner.search.samplers.quasi_random import space_filling


class CpBoSampler:
    name = "cp-bo"

    def __init__(self, knowledge: KnowledgeSession) -> None:
        self.knowledge = knowledge
        self.guided = 0
        self.unguided = 0

    def propose(self, ctx: SampleContext) -> Value | Proposal:
        domain = ctx.var.domain
        if isinstance(domain, CategoricalDomain):
            left = [c for c in domain.choices if c not in ctx.siblings]
            if len(left) == 1:
                return left[0]
        constraints = self.knowledge.constraints_at(ctx.var.var, ctx.path)
        if constraints:
            seed = int(ctx.rng.integers(2**31 - 1))
            answer = self.knowledge.suggest(ctx.var, ctx.path, ctx.siblings, constraints, seed)
            value = answer.x.get(ctx.var.var) if answer is not None else None
            if value is not None and _valid(value, ctx):
                self.guided += 1
                return Proposal(value, answer.mpf)
        self.unguided += 1
        return space_filling(ctx)

    def close(self) -> None:
        return None


def _valid(value: Value, ctx: SampleContext) -> bool:
    domain = ctx.var.domain
    if isinstance(domain, CategoricalDomain):
        return isinstance(value, str) and value in domain.choices and value not in ctx.siblings
    return (
        isinstance(value, list)
        and len(value) == len(domain.low)
        and all(lo <= v <= hi for v, lo, hi in zip(value, domain.low, domain.high, strict=True))
    )


def _factory(*, knowledge: KnowledgeSession | None = None, **_: object) -> CpBoSampler:
    if knowledge is None:
        raise ValueError("cp-bo needs a knowledge session")
    return CpBoSampler(knowledge)


register("cp-bo", _factory, uses_knowledge=True)

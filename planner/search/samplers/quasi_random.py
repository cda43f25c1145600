"""The baseline: a Voronoi sampler (DESIGN.md section 1).

Continuous: draw 10 x dim uniform candidates in the box and keep the one farthest (in the box
scaled to the unit cube) from the existing siblings, so new children fill the Voronoi gaps.
Categorical: a uniform choice among the choices not yet tried.
"""

from __future__ import annotations

import numpy as np

from client.models import CategoricalDomain, ContinuousDomain, Value
from planner.search.samplers import register
from planner.search.samplers.base import SampleContext

CANDIDATES_PER_DIM = 10


def voronoi_point(
    domain: ContinuousDomain,
    siblings: list[list[float]] | np.ndarray,
    rng: np.random.Generator,
) -> list[float]:
    """The farthest of 10 x dim uniform candidates from `siblings` (unit-cube distance)."""
    low = np.asarray(domain.low, dtype=float)
    high = np.asarray(domain.high, dtype=float)
    unit = rng.random((CANDIDATES_PER_DIM * len(low), len(low)))
    if len(siblings):
        existing = (np.asarray(siblings, dtype=float) - low) / (high - low)
        # |u - e|^2 = |u|^2 + |e|^2 - 2 u.e: one matrix product, fast for thousands of siblings
        gaps = (
            (unit * unit).sum(1)[:, None]
            + (existing * existing).sum(1)[None, :]
            - 2.0 * unit @ existing.T
        ).min(axis=1)
        best = unit[int(np.argmax(gaps))]
    else:
        best = unit[0]
    return [float(v) for v in low + best * (high - low)]


def untried_choice(
    domain: CategoricalDomain, siblings: list[Value], rng: np.random.Generator
) -> str:
    """A uniform choice without replacement."""
    left = [c for c in domain.choices if c not in siblings]
    if not left:
        raise ValueError("every choice of this categorical decision has been tried")
    return left[int(rng.integers(len(left)))]


def space_filling(ctx: SampleContext) -> Value:
    domain = ctx.var.domain
    if isinstance(domain, CategoricalDomain):
        return untried_choice(domain, list(ctx.siblings), ctx.rng)
    siblings = ctx.sibling_matrix
    if siblings is None:
        siblings = np.asarray(ctx.siblings, dtype=float).reshape(-1, len(domain.low))
    return voronoi_point(domain, siblings, ctx.rng)


class QuasiRandomSampler:
    name = "quasi-random"

    def propose(self, ctx: SampleContext) -> Value:
        return space_filling(ctx)

    def propose_untried(self, ctx: SampleContext) -> None:
        return None

    def close(self) -> None:
        return None


def _factory(**_: object) -> QuasiRandomSampler:
    return QuasiRandomSampler()


register("quasi-random", _factory)

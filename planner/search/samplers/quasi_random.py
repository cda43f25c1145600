"""The baseline: a Voronoi sampler (DESIGN.md section 1).

Continuous: draw `candidates_per_dim` x dim uniform candidates in the box and keep the one farthest
(in the box scaled to the unit cube) from the existing siblings, so new children fill the Voronoi
gaps. Categorical: a uniform choice among the choices not yet tried.
"""

from __future__ import annotations

import numpy as np

from contract.models import CategoricalDomain, ContinuousDomain, Value
from planner.config import PlanConfig, QuasiRandomConfig
from planner.search.samplers.base import SampleContext


def voronoi_point(
    domain: ContinuousDomain,
    siblings: list[list[float]] | np.ndarray,
    rng: np.random.Generator,
    candidates_per_dim: int = QuasiRandomConfig.candidates_per_dim,
) -> list[float]:
    """The farthest of `candidates_per_dim` x dim uniform candidates from `siblings` (unit-cube
    distance)."""
    low = np.asarray(domain.low, dtype=float)
    high = np.asarray(domain.high, dtype=float)
    unit = rng.random((candidates_per_dim * len(low), len(low)))
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


def space_filling(
    ctx: SampleContext, candidates_per_dim: int = QuasiRandomConfig.candidates_per_dim
) -> Value:
    domain = ctx.var.domain
    if isinstance(domain, CategoricalDomain):
        return untried_choice(domain, list(ctx.siblings), ctx.rng)
    siblings = ctx.sibling_matrix
    if siblings is None:
        siblings = np.asarray(ctx.siblings, dtype=float).reshape(-1, len(domain.low))
    return voronoi_point(domain, siblings, ctx.rng, candidates_per_dim)


class QuasiRandomSampler:
    name = "quasi-random"
    keeps_knowledge = False

    def __init__(self, config: QuasiRandomConfig | None = None) -> None:
        self.config = config if config is not None else QuasiRandomConfig()

    def propose(self, ctx: SampleContext) -> Value:
        return space_filling(ctx, self.config.candidates_per_dim)

    def propose_untried(self, ctx: SampleContext) -> None:
        return None

    def chain(self) -> None:
        return None

    def close(self) -> None:
        return None


def factory(*, config: PlanConfig, **_: object) -> QuasiRandomSampler:
    return QuasiRandomSampler(config.quasi_random)

"""The surrogate knobs, each defined once with its one default and its bounds.

`server.settings` nests `SurrogateConfig` in the service's settings (environment variables
`CPKB_SURROGATE__<KNOB>`, and `CPKB_SURROGATE__OPTIMIZER__<KNOB>` for the maximiser), the
service's engine and fit worker take theirs from it, and `surrogate.optimize` takes its
`OptimizerConfig`; the planner's own maximiser uses the one the service serves with its models.
Kept free of heavy imports so that reading the settings does not load torch.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class OptimizerConfig(BaseModel):
    """NSGA-II's settings when maximising an acquisition. The authors used pop 100 x 100
    generations (`authors()`); the default is cut to what `benchmarks/synthetic_cpbo.py`
    measured to reach the same acquisition values."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    pop_size: int = Field(default=24, ge=4, le=1000)
    """NSGA-II's population."""
    generations: int = Field(default=2, ge=0, le=1000)
    """NSGA-II's generations, the first being the start population (0: raw samples only)."""
    raw_samples: int = Field(default=256, ge=1, le=100_000)
    """Space-filling samples scored before NSGA-II starts from the best of them."""
    mpf_margin: float = Field(default=0.1, ge=0.0, le=1.0)
    """The answer is the most spread candidate (farthest from the excluded and pending points)
    within this fraction of the best value rather than the argmax itself (0: argmax)."""
    mpf_margin_abs: float = Field(default=0.025, ge=0.0, le=1.0)
    """... or within this much of it (absolute): where every value is tiny, spread."""
    spread_walls: bool = True
    """The margin rule's spread counts a continuous variable's walls as mirrors, so that a
    node's children fill the inside of its box; off, the most spread point may lie on a face or
    in a corner, as the quasi-random baseline's Voronoi rule has it
    (`surrogate.avoid.AvoidSet.spread`)."""
    sbx_eta: float = Field(default=15.0, gt=0)
    sbx_prob: float = Field(default=0.9, ge=0.0, le=1.0)
    pm_eta: float = Field(default=20.0, gt=0)
    explore: float = Field(default=0.02, ge=0.0)
    """Score bonus per unit of normalised distance to the excluded and pending points."""
    enumerate_limit: int = Field(default=2048, ge=0)
    """A finite space of at most this many points is enumerated instead of searched."""
    eliminate_duplicates: bool = True

    @staticmethod
    def authors() -> OptimizerConfig:
        return OptimizerConfig(pop_size=100, generations=100, raw_samples=100)


class SurrogateConfig(BaseModel):
    """A type's classifier fits and the suggestions made from them."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    max_inducing: int = Field(default=128, ge=8, le=1024)
    """Inducing points of a type's variational GP classifier (k-means initialised)."""
    max_fit_points: int = Field(default=1000, ge=0)
    """Points a classifier fit trains on at most (0: all): the ones the last fit got wrong or
    was unsure of, then both classes alike; so a fit's cost stops growing with its type."""
    instant_fit_points: int = Field(default=128, ge=0, le=2000)
    """A type without a fit up to this many points gets one at once, in the service's own
    process, while the background fit is on its way (0: wait for the background fit)."""
    instant_fit_iters: int = Field(default=30, ge=1, le=1000)
    """That first fit's optimiser steps (the background fit's warm start takes it from there)."""
    instant_refit_factor: float = Field(default=2.0, ge=0.0, le=100.0)
    """A type whose fit holds fewer than 1/this of its points (and that has at most
    `instant_fit_points`) gets such a short fit too, warm from its fit, while its background
    refit waits in the queue: with many planners at once that queue lags behind the points
    (0: first models only). On: planners at once took fewer rollouts with it, and a planner
    alone, whose queue keeps up, no measurably different number (BENCHMARKS.md, issue 23)."""
    balance_classes: bool = True
    """SMOTE the minority class of a type's points up to the majority before a classifier fit,
    as the paper does. Off, the fit sees the points as they are, so its constant mean (P far
    from any point) follows the type's rate of feasible points instead of a coin flip."""
    pending_ttl_s: float = Field(default=30.0, ge=0)
    """How long a served suggestion stays pending (pushing others away) without an answer."""
    refresh_s: float = Field(default=0.5, ge=0)
    """The service loads a type's new points when they are older than this (one query)."""
    prefit_types: int = Field(default=16, ge=0)
    """Types the service fits at start, the most recently used first."""
    optimizer: OptimizerConfig = OptimizerConfig()
    """How a suggestion maximises its acquisition."""

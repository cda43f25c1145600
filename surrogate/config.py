"""The surrogate knobs that the service and the planner share, each with its one default.

`server.settings` takes its defaults from here (and reads the environment over them), the
service's engine and the planner's copy of the suggestion code start from the same values, and
`surrogate.models` builds its predictors with them. Kept free of heavy imports so that reading
the settings does not load torch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

AdditiveMode = Literal["none", "choices", "decisions"]


@dataclass(frozen=True)
class SurrogateConfig:
    max_inducing: int = 128
    """Inducing points of a type's variational GP classifier (k-means initialised)."""
    max_fit_points: int = 1000
    """Points a classifier fit trains on at most (0: all): the ones the last fit got wrong or
    was unsure of, then both classes alike; so a fit's cost stops growing with its type."""
    instant_fit_points: int = 128
    """A type without a fit up to this many points gets one at once, in the service's own
    process, while the background fit is on its way (0: wait for the background fit)."""
    instant_fit_iters: int = 30
    """That first fit's optimiser steps (the background fit's warm start takes it from there)."""
    instant_refit_factor: float = 2.0
    """A type whose fit holds fewer than 1/this of its points (and that has at most
    `instant_fit_points`) gets such a short fit too, warm from its fit, while its background
    refit waits in the queue: with many planners at once that queue lags behind the points
    (0: first models only). On: planners at once took fewer rollouts with it, and a planner
    alone, whose queue keeps up, no measurably different number (BENCHMARKS.md, issue 23)."""
    additive: AdditiveMode = "none"
    """Additive kernel terms of a type's classifier beside its main kernel (`none`, `choices`
    or `decisions`: `surrogate.additive`)."""
    balance_classes: bool = True
    """SMOTE the minority class of a type's points up to the majority before a classifier fit,
    as the paper does. Off, the fit sees the points as they are, so its constant mean (P far
    from any point) follows the type's rate of feasible points instead of a coin flip."""
    prior_weight: float = 0.45
    """How far the stated prior moves P(feasible) away from 0.5 at an observed point."""
    prior_lengthscale: float = 0.1
    """The stated prior's reach in the unit cube, per sqrt(D)."""
    recent_weight: float = 0.5
    """How far a point not yet fitted moves P(feasible) toward its label, at the point."""
    recent_lengthscale: float = 0.05
    """Its reach per sqrt(D): half the prior's, since a fit will follow."""
    pending_ttl_s: float = 30.0
    """How long a served suggestion stays pending (pushing others away) without an answer."""
    mpf_margin: float = 0.1
    """Suggest answers the most spread point within this fraction of the best MPF (0: argmax)."""
    mpf_margin_abs: float = 0.025
    """... or within this much of it (absolute P(feasible)): where every value is tiny, spread."""
    spread_walls: bool = True
    """The margin rule's spread counts a continuous variable's walls as mirrors, so that a
    node's children fill the inside of its box; off, the most spread point may lie on a face or
    in a corner, as the quasi-random baseline's Voronoi rule has it."""
    pop_size: int = 24
    """NSGA-II's population when maximising an acquisition."""
    generations: int = 2
    """NSGA-II's generations, the first being the start population (0: raw samples only)."""
    raw_samples: int = 256
    """Space-filling samples scored before NSGA-II starts from the best of them."""
    refresh_s: float = 0.5
    """The service loads a type's new points when they are older than this (one query)."""
    prefit_types: int = 16
    """Types the service fits at start, the most recently used first."""

"""One MPF suggestion from built constraint terms: the part the service and an in-process
planner share, so that both answer the same point for the same models, request and seed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from client.models import SuggestedPoint
from surrogate.acquisition import MPF, ConstraintTerm
from surrogate.encoding import Domain, SpaceEncoder, Value
from surrogate.optimize import OptimizerConfig, maximize_batch


def mpf_points(
    terms: Sequence[ConstraintTerm],
    space: Mapping[str, Domain],
    *,
    fixed: Mapping[str, Value],
    exclude: Sequence[Mapping[str, Value]],
    pending: Sequence[Mapping[str, Value]],
    lookahead: Sequence[str],
    seed: int,
    config: OptimizerConfig,
    n: int,
) -> list[SuggestedPoint]:
    """Up to `n` spread MPF maximisers (see `maximize_batch`), each with every type's
    P(feasible). Raises EncodingError or SpaceExhausted as `maximize_batch` does."""
    mpf = MPF(list(terms))
    found = maximize_batch(
        mpf,
        space,
        fixed=fixed,
        exclude=exclude,
        pending=pending,
        seed=seed,
        config=config,
        n=n,
        distinct=[var for var in space if var not in lookahead],
    )
    xs = [s.x for s in found]
    per_term = mpf.per_term(SpaceEncoder(space).columns(xs))
    return [_point(x, terms, per_term[:, i]) for i, x in enumerate(xs)]


def _point(x: dict, terms: Sequence[ConstraintTerm], per_term: np.ndarray) -> SuggestedPoint:
    """One answer point: each type's P(feasible) (a type bound twice: its lower one), and MPF."""
    p_feasible: dict[str, float] = {}
    for term, p in zip(terms, per_term, strict=True):
        p_feasible[term.name] = min(float(p), p_feasible.get(term.name, 1.0))
    mpf = min(p_feasible.values()) if p_feasible else 0.5
    return SuggestedPoint(x=x, mpf=mpf, p_feasible=p_feasible)

"""One MPF suggestion from built constraint terms: the part the service and an in-process
planner share, so that both answer the same point for the same models, request and seed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from client.models import SuggestedPoint, SuggestIn, SuggestOut
from surrogate.acquisition import MPF, ConstraintTerm
from surrogate.encoding import SpaceEncoder, Value
from surrogate.optimize import OptimizerConfig, maximize_batch
from surrogate.pending import PendingBook


def mpf_points(
    terms: Sequence[ConstraintTerm],
    request: SuggestIn,
    *,
    pending: Sequence[Mapping[str, Value]],
    seed: int,
    config: OptimizerConfig,
) -> list[SuggestedPoint]:
    """Up to `request.n` spread MPF maximisers (see `maximize_batch`), each with every type's
    P(feasible). Raises EncodingError or SpaceExhausted as `maximize_batch` does."""
    mpf = MPF(list(terms))
    found = maximize_batch(
        mpf,
        request.space,
        fixed=request.fixed,
        exclude=request.exclude,
        pending=pending,
        seed=seed,
        config=config,
        n=request.n,
        distinct=[var for var in request.space if var not in request.lookahead],
    )
    xs = [s.x for s in found]
    per_term = mpf.per_term(SpaceEncoder(request.space).columns(xs))
    return [_point(x, terms, per_term[:, i]) for i, x in enumerate(xs)]


def served(
    request: SuggestIn,
    points: list[SuggestedPoint],
    book: PendingBook,
    key: str,
    **extra: object,
) -> SuggestOut:
    """The answer to `request`, its points recorded as pending in `book` under `key` (the
    lookahead variables are only a hint and are not recorded)."""
    binds = [(c.type_id, c.bind) for c in request.constraints]
    for point in points:
        proposed = {v: value for v, value in point.x.items() if v not in request.lookahead}
        book.add(key, proposed, binds)
    first = points[0]
    return SuggestOut(
        x=first.x,
        mpf=first.mpf,
        p_feasible=first.p_feasible,
        batch=points if request.n > 1 else [],
        **extra,
    )


def _point(x: dict, terms: Sequence[ConstraintTerm], per_term: np.ndarray) -> SuggestedPoint:
    """One answer point: each type's P(feasible) (a type bound twice: its lower one), and MPF."""
    p_feasible: dict[str, float] = {}
    for term, p in zip(terms, per_term, strict=True):
        p_feasible[term.name] = min(float(p), p_feasible.get(term.name, 1.0))
    mpf = min(p_feasible.values()) if p_feasible else 0.5
    return SuggestedPoint(x=x, mpf=mpf, p_feasible=p_feasible)

"""Acquisition functions over the *free* variables of a search.

An acquisition is a callable `columns -> scores (n,)` (see `surrogate.encoding` for columns), to be
maximised by `surrogate.optimize.maximize`. Fixed variables are bound when the acquisition is built,
so the optimiser only ever sees the variables it chooses.

Like BoTorch's `X_pending`, the points served but not answered yet belong to the acquisition
(`PendingPoints`): it is lowered around them, so that planners asking at the same moment for the
same space do not all get one point. The optimiser measures how far a candidate is from them
(it does so for its own spread anyway) and maximises what the acquisition makes of that.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from surrogate.domains import Domain, Value
from surrogate.encoding import Columns, EncodingError, SpaceEncoder, encoder_for, value_column
from surrogate.predictors import FeasibilityPredictor, RegressionPredictor


@dataclass(frozen=True)
class PendingPoints:
    """Points served but not answered yet (search variables; a point may give only some) and
    the penalty around them: `penalty` at a pending point, a Gaussian of `radius` (in
    normalised distance) around it."""

    points: Sequence[Mapping[str, Value]] = ()
    penalty: float = 0.3
    radius: float = 0.1

    def penalty_at(self, distances: np.ndarray) -> np.ndarray:
        """`(n,)` the score removed from candidates at `(n, k)` normalised distances to the
        pending points (the nearest one counts)."""
        if distances.shape[1] == 0:
            return np.zeros(len(distances))
        return self.penalty * np.exp(-0.5 * (distances / self.radius) ** 2).max(axis=1)


NO_PENDING = PendingPoints()


class Acquisition(Protocol):
    """Scores of candidate columns, and the pending points the optimiser keeps away from."""

    @property
    def pending(self) -> PendingPoints: ...

    def __call__(self, cols: Mapping[str, np.ndarray]) -> np.ndarray: ...


def _fixed_columns(
    encoder: SpaceEncoder, rename: Mapping[str, str], fixed: Mapping[str, Value]
) -> Columns:
    """1-row columns for the encoder's variables whose search variable is fixed."""
    cols: Columns = {}
    for var in encoder.vars:
        search_var = rename.get(var.name, var.name)
        if search_var in fixed:
            cols[var.name] = value_column(search_var, var.domain, [fixed[search_var]])
    return cols


@dataclass(frozen=True)
class ConstraintTerm:
    """One constraint type in an MPF: its predictor, its decision space (labels -> domains) and
    `bind`: label -> search variable. Labels bound to fixed variables are resolved at build time."""

    name: str
    predictor: FeasibilityPredictor
    encoder: SpaceEncoder
    bind: Mapping[str, str]
    fixed_cols: Columns

    @classmethod
    def build(
        cls,
        name: str,
        predictor: FeasibilityPredictor,
        space: Mapping[str, Domain],
        bind: Mapping[str, str],
        fixed: Mapping[str, Value],
    ) -> ConstraintTerm:
        encoder = encoder_for(space)
        missing = [label for label in space if label not in bind]
        if missing:
            raise EncodingError(f"bind.{missing[0]}", "decision label is not bound")
        return cls(name, predictor, encoder, dict(bind), _fixed_columns(encoder, bind, fixed))

    def proba(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        return self.predictor.proba(self.encoder.encode(self.columns(cols)))

    def columns(self, cols: Mapping[str, np.ndarray], rows: int | None = None) -> Columns:
        """The type's columns (by decision label) of the search's `cols`; with `rows`, each
        broadcast to that many rows (a fixed label's column has one)."""
        own: Columns = dict(self.fixed_cols)
        for label, var in self.bind.items():
            if label not in own:
                own[label] = cols[var]
        if rows is None:
            return own
        return {k: np.broadcast_to(c, (rows, *np.shape(c)[1:])) for k, c in own.items()}


@dataclass(frozen=True)
class MPF:
    """Minimum probability of feasibility: alpha(x) = min_i P(CP_i feasible | x)."""

    terms: Sequence[ConstraintTerm]
    pending: PendingPoints = field(default=NO_PENDING)

    def per_term(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        """`(k, n)` P(feasible) of each term. The terms of one type (one predictor, one encoder)
        are asked together, their inputs stacked: a request that looks ahead binds a few types
        some thirty times, and each call has a fixed cost. A predictor answers each row on its
        own, so the values are those of the terms asked one by one."""
        n = max((len(c) for c in cols.values()), default=1)
        groups: dict[tuple[int, int], list[int]] = {}
        for i, term in enumerate(self.terms):
            groups.setdefault((id(term.predictor), id(term.encoder)), []).append(i)
        out = np.empty((len(self.terms), n))
        for members in groups.values():
            terms = [self.terms[i] for i in members]
            own = [term.columns(cols, n) for term in terms]
            stacked = {label: np.concatenate([o[label] for o in own]) for label in own[0]}
            z = terms[0].encoder.encode(stacked)
            out[members] = np.asarray(terms[0].predictor.proba(z)).reshape(len(members), n)
        return out

    def __call__(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        return self.per_term(cols).min(axis=0)


@dataclass(frozen=True)
class Scored:
    """Any score of candidate columns as an acquisition (with no pending points unless given)."""

    score: Callable[[Mapping[str, np.ndarray]], np.ndarray]
    pending: PendingPoints = field(default=NO_PENDING)

    def __call__(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        return self.score(cols)


@dataclass(frozen=True)
class UCB:
    """GP-UCB `mu + sqrt(beta) sigma`, in the standardised units of the fit (ordering is what
    counts); `space` is the regression's whole input space, `fixed` pins earlier decisions."""

    predictor: RegressionPredictor
    encoder: SpaceEncoder
    beta: float
    fixed_cols: Columns
    pending: PendingPoints = field(default=NO_PENDING)

    @classmethod
    def build(
        cls,
        predictor: RegressionPredictor,
        space: Mapping[str, Domain],
        beta: float = 2.0,
        fixed: Mapping[str, Value] | None = None,
    ) -> UCB:
        encoder = encoder_for(space)
        return cls(predictor, encoder, beta, _fixed_columns(encoder, {}, fixed or {}))

    def __call__(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        own = {**{k: v for k, v in cols.items() if k not in self.fixed_cols}, **self.fixed_cols}
        mean, std = self.predictor.predict(self.encoder.encode(own))
        scale = self.predictor.y_scale
        return (mean - self.predictor.y_shift) / scale + np.sqrt(self.beta) * std / scale


def ucb(
    predictor: RegressionPredictor,
    space: Mapping[str, Domain],
    beta: float = 2.0,
    fixed: Mapping[str, Value] | None = None,
) -> UCB:
    """Shorthand for `UCB.build`."""
    return UCB.build(predictor, space, beta, fixed)

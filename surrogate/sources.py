"""Serving a type's model from its points, and a `ModelSource` held in memory.

`served_predictor` is what a request is answered with: the latest fit (or the stated prior),
the points that arrived since weighed in, and the prior answering for categorical choices the
fit never saw. The service's engine serves its types with it; `InMemoryModels` fits and serves
types in this process the same way, so that samplers and knowledge tests run without a server.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from surrogate.config import SurrogateConfig
from surrogate.domains import Domain, Value
from surrogate.encoding import SpaceEncoder, encoder_for
from surrogate.models import MIN_POINTS, Fit, fit_classifier
from surrogate.predictors import FeasibilityPredictor, PriorPredictor, RecentPoints, UnseenChoices
from surrogate.suggest import TypeModel

Seen = tuple[tuple[slice, np.ndarray], ...]


def prior(z: np.ndarray, y: np.ndarray) -> PriorPredictor:
    """The stated prior on points `z` labelled `y` (True: feasible)."""
    return PriorPredictor(feasible=z[y], infeasible=z[~y])


def needs_model(y: np.ndarray) -> bool:
    """Whether labels `y` call for a fit (enough points, both classes) rather than the prior."""
    return len(y) >= MIN_POINTS and bool(y.any()) and not bool(y.all())


def seen_choices(encoder: SpaceEncoder, z: np.ndarray) -> Seen:
    """Per categorical variable of the encoding: its columns and the distinct rows of `z` there
    (the choices the fitted points hold)."""
    return tuple(
        (columns, np.unique(z[:, columns], axis=0)) for columns, _ in encoder.choice_rows()
    )


def served_predictor(
    base: FeasibilityPredictor, z: np.ndarray, y: np.ndarray, n_fitted: int, seen: Seen
) -> FeasibilityPredictor:
    """`base` (fitted on the first `n_fitted` of `z`, `y`; `seen`: its choices, empty for the
    prior) with the later points weighed in and unseen choices left to the prior."""
    predictor = base
    if n_fitted < len(y):
        recent, labels = z[n_fitted:], y[n_fitted:]
        predictor = RecentPoints(predictor, recent[labels], recent[~labels])
    if seen:
        predictor = UnseenChoices(predictor, prior(z, y), seen)
    return predictor


@dataclass
class _Type:
    space: dict[str, Domain]
    encoder: SpaceEncoder
    z: np.ndarray
    y: np.ndarray
    fit: Fit | None = None
    base: FeasibilityPredictor | None = None
    n_fitted: int = 0
    seen: Seen = field(default=())


class InMemoryModels:
    """Types and their points in this process, fitted as the service fits them (seed 0, warm
    from the previous fit) whenever a model is asked for after points were added."""

    def __init__(self, *, max_inducing: int = SurrogateConfig().max_inducing) -> None:
        self.max_inducing = max_inducing
        self._types: dict[str, _Type] = {}
        self.fits = 0

    def add(
        self,
        type_id: str,
        space: Mapping[str, Domain],
        points: Sequence[tuple[Mapping[str, Value], bool]],
    ) -> None:
        """Points `(x by decision label, feasible)` of a type (created with `space` if new)."""
        entry = self._types.get(type_id)
        if entry is None:
            encoder = encoder_for(space)
            entry = _Type(dict(space), encoder, np.zeros((0, encoder.dim)), np.zeros(0, bool))
            self._types[type_id] = entry
        if points:
            z = entry.encoder.encode_points([x for x, _ in points])
            entry.z = np.vstack([entry.z, z])
            entry.y = np.concatenate([entry.y, np.asarray([ok for _, ok in points], bool)])

    def model(self, type_id: str) -> TypeModel:
        """The type's current model; KeyError for a type never added."""
        entry = self._types[type_id]
        if entry.base is None or entry.n_fitted < len(entry.y):
            self._refit(entry)
        assert entry.base is not None
        predictor = served_predictor(entry.base, entry.z, entry.y, entry.n_fitted, entry.seen)
        return TypeModel(entry.space, predictor, str(entry.n_fitted), entry.n_fitted, len(entry.y))

    def _refit(self, entry: _Type) -> None:
        if not needs_model(entry.y):
            entry.base, entry.seen = prior(entry.z, entry.y), ()
        else:
            fit = fit_classifier(
                entry.z, entry.y, seed=0, warm=entry.fit, max_inducing=self.max_inducing
            )
            self.fits += 1
            entry.fit, entry.base = fit, fit.predictor
            entry.seen = seen_choices(entry.encoder, entry.z)
        entry.n_fitted = len(entry.y)

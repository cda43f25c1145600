"""Predictor snapshots: JSON out, the same predictor back, to the last bit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surrogate import snapshot
from surrogate.models import fit_classifier, fit_label_regression
from surrogate.predictors import PriorPredictor, RecentPoints, UnseenChoices


def _data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    z = np.random.default_rng(seed).random((n, 4))
    z[:, 3] = (z[:, 3] > 0.5).astype(float)  # a one-hot-like categorical column
    return z, z[:, 0] + 0.5 * z[:, 1] > 0.7


def _through_json(predictor: object) -> object:
    return snapshot.load(json.loads(json.dumps(snapshot.dump(predictor))))


def test_every_kind_comes_back_answering_the_same() -> None:
    z, y = _data(40, 0)
    probe = np.random.default_rng(1).random((64, 4))
    vgp = fit_classifier(z, y, seed=0, max_iters=20).predictor
    prior = PriorPredictor(z[y], z[~y])
    predictors = [
        prior,
        vgp,
        fit_label_regression(z, y, seed=0).predictor,
        RecentPoints(vgp, z[:2], z[2:5]),
        UnseenChoices(RecentPoints(vgp, z[:1], z[1:2]), prior, ((slice(3, 4), np.ones((1, 1))),)),
    ]
    for predictor in predictors:
        back = _through_json(predictor)
        assert type(back) is type(predictor)
        np.testing.assert_array_equal(back.proba(probe), predictor.proba(probe))


def test_a_bad_snapshot_is_refused_with_where_it_is_wrong() -> None:
    good = snapshot.dump(PriorPredictor(np.zeros((1, 2)), np.ones((2, 2))))
    with pytest.raises(snapshot.SnapshotError, match="unknown predictor kind 'gp'"):
        snapshot.load({**good, "kind": "gp"})
    with pytest.raises(snapshot.SnapshotError, match=r"predictor\.feasible: not an encoded array"):
        snapshot.load({**good, "feasible": {"shape": [3, 2], "data": "AAAA"}})
    with pytest.raises(snapshot.SnapshotError, match="lacks 'infeasible'"):
        snapshot.load({"kind": "prior", "feasible": good["feasible"]})
    z, y = _data(40, 0)
    vgp = snapshot.dump(fit_classifier(z, y, seed=0, max_iters=20).predictor)
    terms = [{"dims": vgp["lengthscale"], "lengthscale": vgp["lengthscale"], "outputscale": 1.0}]
    with pytest.raises(snapshot.SnapshotError, match="additive kernel terms"):
        snapshot.load({**vgp, "terms": terms})  # a stored fit of the retired kernel: fit anew
    with pytest.raises(TypeError, match="cannot snapshot"):
        snapshot.dump(object())  # type: ignore[arg-type]

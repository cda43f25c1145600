"""Every predictor kind says how unsure it is: its latent posterior sd over the prior's, 1 where
no data bears on a point (real gpytorch fits on small data)."""

from __future__ import annotations

import numpy as np

from surrogate.models import fit_classifier, fit_label_regression
from surrogate.predictors import PriorPredictor, RecentPoints, UnseenChoices, _reach
from surrogate.snapshot import dump, load


def corner(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Points in the lower-left corner only, feasible right of z0 = 0.2."""
    z = np.random.default_rng(seed).random((n, 2)) * 0.4
    return z, z[:, 0] > 0.2


FAR = np.array([[0.9, 0.9], [0.95, 0.2], [0.8, 0.6]])


def test_a_fit_is_unsure_far_from_its_data_and_sure_next_to_it() -> None:
    z, y = corner(40, 0)
    fit = fit_classifier(z, y, seed=0, max_iters=60)
    near, far = fit.predictor.uncertainty(z), fit.predictor.uncertainty(FAR)
    assert fit.kind == "vgp"
    assert np.median(near) < 0.6 and near.max() < 0.7
    assert far.min() > 0.95 and far.max() <= 1.0
    again = load(dump(fit.predictor))  # a planner's copy is as unsure as the service's
    assert np.array_equal(again.uncertainty(FAR), far)


def test_the_prior_is_unsure_by_its_distance_to_the_data() -> None:
    point = np.array([[0.3, 0.3]])
    prior = PriorPredictor(feasible=point, infeasible=np.zeros((0, 2)))
    probes = np.array([[0.3, 0.3], [0.35, 0.3], [0.45, 0.3], [0.9, 0.9]])
    u = prior.uncertainty(probes)
    assert u[0] < 1e-6 and u[-1] > 0.999
    assert (np.diff(u) > 0).all()  # further away, more unsure
    empty = PriorPredictor(feasible=np.zeros((0, 2)), infeasible=np.zeros((0, 2)))
    assert (empty.uncertainty(probes) == 1.0).all()
    # The nearest point found by a tree is the one a sweep over every point finds.
    rng = np.random.default_rng(4)
    many = PriorPredictor(feasible=rng.random((50, 3)), infeasible=rng.random((70, 3)))
    grid = rng.random((200, 3))
    swept = _reach(grid, np.vstack([many.feasible, many.infeasible]), many.lengthscale)
    assert np.allclose(many.uncertainty(grid), np.sqrt(1 - swept**2), atol=1e-9)


def test_new_points_make_a_fit_surer_next_to_them_only() -> None:
    z, y = corner(40, 1)
    fit = fit_classifier(z, y, seed=0, max_iters=60)
    recent = RecentPoints(fit.predictor, feasible=FAR[:1], infeasible=np.zeros((0, 2)))
    before, after = fit.predictor.uncertainty(FAR), recent.uncertainty(FAR)
    assert before[0] > 0.95 and after[0] < 0.05
    assert np.allclose(after[1:], before[1:], atol=0.01)
    assert (after <= before).all()


def test_an_untried_choice_is_as_unsure_as_the_prior() -> None:
    from surrogate.domains import CategoricalDomain, ContinuousDomain
    from surrogate.encoding import SpaceEncoder

    space = {
        "d": CategoricalDomain(choices=["front", "top"]),
        "p": ContinuousDomain(low=[0.0], high=[1.0]),
    }
    encoder = SpaceEncoder(space)
    values = np.random.default_rng(2).random(30)
    z = encoder.encode_points([{"d": "top", "p": [float(v)]} for v in values])
    y = values > 0.5
    fit = fit_classifier(z, y, seed=0, max_iters=60)
    prior = PriorPredictor(feasible=z[y], infeasible=z[~y])
    columns = slice(0, z.shape[1] - 1)
    guarded = UnseenChoices(fit.predictor, prior, ((columns, np.unique(z[:, columns], axis=0)),))
    top = encoder.encode_points([{"d": "top", "p": [0.4]}])
    front = encoder.encode_points([{"d": "front", "p": [0.4]}])
    assert guarded.uncertainty(top)[0] == fit.predictor.uncertainty(top)[0] < 0.7
    assert guarded.uncertainty(front)[0] == prior.uncertainty(front)[0] > 0.9


def test_the_label_regression_variant_is_unsure_away_from_its_data() -> None:
    z, y = corner(30, 3)
    fit = fit_label_regression(z, y, seed=0)
    near, far = fit.predictor.uncertainty(z), fit.predictor.uncertainty(FAR)
    assert fit.kind == "label-regression"
    assert near.max() < far.min() and far.max() <= 1.0 and near.min() >= 0.0

"""GP surrogates: real gpytorch fits on small data."""

from __future__ import annotations

import gpytorch
import numpy as np
import pytest
import torch

from surrogate.models import _SVGP, fit_classifier, fit_label_regression, fit_regression
from surrogate.predictors import PriorPredictor, VGPPredictor, _reach


def half_space(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    z = np.random.default_rng(seed).random((n, 3))
    return z, z[:, 0] + 0.5 * z[:, 1] > 0.7


def test_classifier_learns_a_half_space() -> None:
    z, y = half_space(80, 0)
    fit = fit_classifier(z, y, seed=0, max_iters=100)
    zt, yt = half_space(500, 1)
    assert fit.kind == "vgp" and fit.n_fitted == 80
    assert ((fit.predictor.proba(zt) > 0.5) == yt).mean() > 0.9
    assert fit.train_accuracy is not None and fit.train_accuracy > 0.9
    assert len(fit.lengthscales or []) == 3
    assert fit.lengthscales[2] > fit.lengthscales[0]  # the irrelevant input matters least


def test_cached_predictor_matches_gpytorch() -> None:
    z, y = half_space(40, 2)
    fit = fit_classifier(z, y, seed=0, max_iters=30)
    model = _SVGP(torch.as_tensor(fit.warm_state["model"]["variational_strategy.inducing_points"]))
    model = model.double()
    model.load_state_dict(fit.warm_state["model"])
    model.eval()
    zt = np.random.default_rng(3).random((50, 3))
    with torch.no_grad():
        latent = model(torch.as_tensor(zt))
        p = gpytorch.likelihoods.BernoulliLikelihood()(latent).mean.numpy()
    assert isinstance(fit.predictor, VGPPredictor)
    assert np.allclose(fit.predictor.proba(zt), p, atol=1e-4)


@pytest.mark.slow
def test_inducing_points_are_bounded_and_warm_start_is_cheaper() -> None:
    z, y = half_space(200, 4)
    cold = fit_classifier(z, y, seed=0, max_inducing=32, max_iters=150)
    assert cold.predictor.inducing.shape == (32, 3)
    z2, y2 = half_space(20, 5)
    warm = fit_classifier(
        np.vstack([z, z2]), np.concatenate([y, y2]), seed=0, warm=cold, max_inducing=32
    )
    assert warm.iterations < cold.iterations
    zt, yt = half_space(500, 6)
    assert ((warm.predictor.proba(zt) > 0.5) == yt).mean() > 0.9


def test_prior_for_few_points_or_one_class() -> None:
    z = np.array([[0.2, 0.2], [0.8, 0.8]])
    fit = fit_classifier(z, np.array([False, False]), seed=0)
    assert fit.kind == "prior" and isinstance(fit.predictor, PriorPredictor)
    p = fit.predictor.proba(np.array([[0.2, 0.2], [0.5, 0.5], [0.2, 0.9]]))
    assert p[0] < 0.1 and p[1] > p[0] and abs(p[2] - 0.5) < 0.05
    mixed = fit_classifier(z, np.array([True, False]), seed=0)
    assert mixed.kind == "prior" and mixed.predictor.proba(z[:1])[0] > 0.9


def test_reach_is_the_nearest_points_similarity() -> None:
    rng = np.random.default_rng(3)
    z, points = rng.random((64, 5)), rng.random((40, 5))
    ell2 = (0.2**2) * 5
    every = np.exp(-0.5 * ((z[:, None, :] - points[None, :, :]) ** 2).sum(-1) / ell2)
    assert _reach(z, points, 0.2) == pytest.approx(every.max(axis=1), rel=1e-9, abs=1e-12)
    assert _reach(points[:3], points, 0.2) == pytest.approx(np.ones(3))
    assert _reach(z, points[:0], 0.2).tolist() == [0.0] * 64


def test_the_stated_prior_is_a_coin_flip_far_from_its_points_and_leans_near_them() -> None:
    """Far from every point P(feasible) is 0.5 however many failures there are; near a known
    point it moves toward its label by the prior's weight."""
    rng = np.random.default_rng(3)
    z = rng.random((8, 2))
    far = np.array([[5.0, 5.0]])
    plain = PriorPredictor(feasible=z[:0], infeasible=z)
    assert plain.proba(far)[0] == pytest.approx(0.5)
    mixed_plain = PriorPredictor(feasible=z[:1], infeasible=z[1:])
    probe = rng.random((16, 2))
    stated = 0.5 + mixed_plain.weight * (
        _reach(probe, z[:1], mixed_plain.lengthscale)
        - _reach(probe, z[1:], mixed_plain.lengthscale)
    )
    assert mixed_plain.proba(probe) == pytest.approx(stated)


def test_a_counted_prior_grows_surer_with_each_point_where_the_nearest_one_saturates() -> None:
    """`strength` s > 0: a Beta prior of s pseudo-points updated by kernel-weighted counts, so a
    choice that failed once is rated 1/3 (s = 2) and one that failed five times 1/7, where the
    nearest-point form rates both alike; far from every point it stays at the centre, and
    points joined by `counted` count as the prior's own."""
    once = np.array([[0.0, 0.0]])
    often = np.zeros((5, 2))
    none = np.zeros((0, 2))
    nearest_once, nearest_often = PriorPredictor(none, once), PriorPredictor(none, often)
    assert nearest_once.proba(once)[0] == pytest.approx(nearest_often.proba(once)[0])
    counted_once, counted_often = nearest_once.counted(2.0), nearest_often.counted(2.0)
    assert counted_once.proba(once)[0] == pytest.approx(1 / 3, abs=1e-9)
    assert counted_often.proba(once)[0] == pytest.approx(1 / 7, abs=1e-9)
    far = np.array([[5.0, 5.0]])
    assert counted_often.proba(far)[0] == pytest.approx(0.5)
    joined = counted_once.counted(2.0, feasible=once, infeasible=np.zeros((4, 2)))
    assert len(joined.feasible) == 1 and len(joined.infeasible) == 5
    assert joined.proba(once)[0] == pytest.approx(2 / 8, abs=1e-9)


@pytest.mark.slow
def test_imbalanced_classes_still_find_the_small_feasible_region() -> None:
    rng = np.random.default_rng(7)
    z = rng.random((80, 2))
    y = (z[:, 0] > 0.75) & (z[:, 1] > 0.6)  # ~10% feasible
    fit = fit_classifier(z, y, seed=0, max_iters=100)
    assert fit.predictor.proba(np.array([[0.9, 0.8]]))[0] > 0.5
    assert fit.predictor.proba(np.array([[0.2, 0.2]]))[0] < 0.5


def test_without_balancing_a_fit_rates_unexplored_points_at_its_types_rate() -> None:
    """Labels with no structure, one in ten feasible: SMOTE lifts the minority so the fit says
    about a coin flip's worth everywhere; fitted as they are, the points say about one in ten."""
    rng = np.random.default_rng(0)
    z, y = rng.random((80, 3)), rng.random(80) < 0.1
    elsewhere = np.random.default_rng(1).random((200, 3))
    balanced = fit_classifier(z, y, seed=0).predictor.proba(elsewhere).mean()
    as_they_are = fit_classifier(z, y, seed=0, balance=False).predictor.proba(elsewhere).mean()
    assert as_they_are < 0.15 and balanced > as_they_are + 0.05


def test_regression_fits_and_reports_uncertainty() -> None:
    rng = np.random.default_rng(8)
    z = rng.random((30, 2))
    y = np.sin(6 * z[:, 0]) + 0.1 * z[:, 1]
    fit = fit_regression(z, y, seed=0, max_iters=80)
    mean, std = fit.predictor.predict(np.array([[0.25, 0.5], [0.25, 0.5]]))
    assert abs(mean[0] - np.sin(1.5)) < 0.15
    _far_mean, far_std = fit.predictor.predict(np.array([[3.0, 3.0]]))
    assert far_std[0] > 5 * std[0]
    again = fit_regression(z, y, seed=0, warm=fit, max_iters=80)
    assert again.iterations <= fit.iterations


def test_label_regression_variant_gives_probabilities() -> None:
    z, y = half_space(60, 9)
    fit = fit_label_regression(z, y, seed=0)
    zt, yt = half_space(300, 10)
    p = fit.predictor.proba(zt)
    assert fit.kind == "label-regression" and p.min() >= 0 and p.max() <= 1
    assert ((p > 0.5) == yt).mean() > 0.85


def test_recent_points_move_a_fit_until_the_next_one_takes_them_in() -> None:
    """Points that arrived after a fit lower P(feasible) next to a new failure and raise it
    next to a new success, and leave it alone far from both."""
    from surrogate.predictors import RecentPoints

    z, y = half_space(60, 3)
    fit = fit_classifier(z, y, seed=0, max_iters=60)
    failed, passed, far = np.array([[0.9, 0.9, 0.5]]), np.array([[0.1, 0.1, 0.5]]), [0.9, 0.1, 0.0]
    recent = RecentPoints(fit.predictor, feasible=passed, infeasible=failed)
    probes = np.array([failed[0], passed[0], far])
    before, after = fit.predictor.proba(probes), recent.proba(probes)
    assert after[0] < 0.6 * before[0] and before[0] > 0.8
    assert after[1] > before[1] + 0.4 * (1 - before[1]) and before[1] < 0.2
    assert abs(after[2] - before[2]) < 0.05
    assert ((after >= 0) & (after <= 1)).all()


def test_a_choice_no_point_holds_gets_the_prior_not_the_fits_extrapolation() -> None:
    from surrogate.domains import CategoricalDomain, ContinuousDomain
    from surrogate.encoding import SpaceEncoder
    from surrogate.predictors import UnseenChoices

    space = {
        "d": CategoricalDomain(choices=["front", "right", "top"]),
        "p": ContinuousDomain(low=[0.0], high=[1.0]),
    }
    encoder = SpaceEncoder(space)
    rng = np.random.default_rng(0)
    points = [{"d": "right", "p": [float(v)]} for v in rng.random(40)]
    z = encoder.encode_points(points)
    y = z[:, -1] > 0.8  # rarely feasible: the fit's base rate is low
    fit = fit_classifier(z, y, seed=0, max_iters=60)
    prior = PriorPredictor(feasible=z[y], infeasible=z[~y])
    columns = slice(0, 3)
    guarded = UnseenChoices(fit.predictor, prior, ((columns, np.unique(z[:, columns], axis=0)),))
    right = encoder.encode_points([{"d": "right", "p": [0.3]}])
    front = encoder.encode_points([{"d": "front", "p": [0.3]}])
    assert guarded.proba(right)[0] == fit.predictor.proba(right)[0] < 0.3
    assert guarded.proba(front)[0] == prior.proba(front)[0] > 0.45


def test_a_large_type_trains_on_a_bounded_balanced_subset() -> None:
    """A fit trains on at most `max_points` points: every minority point up to half of them,
    the rest of the majority; so a large type costs what a small one does."""
    from surrogate.models import _training_subset

    rng = np.random.default_rng(6)
    z = rng.random((5000, 3))
    y = z[:, 0] > 0.9  # 10 % feasible: the minority
    subset = _training_subset(z, y, 400, 0, None)
    assert len(subset) == 400 and len(np.unique(subset)) == 400
    assert 180 <= int(y[subset].sum()) <= 220  # balanced, not 10 %
    same = _training_subset(
        np.vstack([z, rng.random((50, 3))]), np.r_[y, np.ones(50, bool)], 400, 0, None
    )
    assert len(np.intersect1d(subset, same)) > 300  # a refit keeps most of the same points
    assert np.array_equal(_training_subset(z[:300], y[:300], 400, 0, None), np.arange(300))


class _WrongInASlice:
    """A last fit that knows the half space except in a thin slice, where it is wrong."""

    def proba(self, z: np.ndarray) -> np.ndarray:
        truth = z[:, 0] + 0.5 * z[:, 1] > 0.7
        return np.where(truth != (z[:, 2] < 0.004), 0.9, 0.1)


def test_points_the_last_fit_got_wrong_are_trained_on() -> None:
    from surrogate.models import BOUNDARY_SHARE, _training_subset

    z, y = half_space(4000, 7)
    subset = _training_subset(z, y, 1000, 0, _WrongInASlice())
    missed = np.flatnonzero(z[:, 2] < 0.004)
    assert 0 < len(missed) <= 1000 * BOUNDARY_SHARE
    assert set(missed) <= set(subset)


@pytest.mark.slow
def test_fit_cost_stops_growing_with_the_points() -> None:
    """Structure, not clocks: a fit of 6,000 points trains on as many points, with as many
    inducing points, as one of 600, and costs about as much CPU (generous bound)."""
    import time

    def fit(n: int) -> tuple[object, float]:
        z, y = half_space(n, 8)
        cpu = time.process_time()
        result = fit_classifier(z, y, seed=0, max_points=600, max_inducing=32, max_iters=40)
        return result, time.process_time() - cpu

    small, small_cpu = fit(600)
    large, large_cpu = fit(6000)
    assert small.n_trained == large.n_trained == 600 and large.n_fitted == 6000
    assert small.n_inducing == large.n_inducing == 32
    assert large_cpu < 4 * small_cpu + 1.0


def test_a_cold_fit_starts_from_the_feasible_rates_near_its_inducing_points() -> None:
    z = np.random.default_rng(3).random((300, 2))
    y = z[:, 0] > 0.5
    start = fit_classifier(z, y, seed=0, max_iters=0)  # no training step: the start alone
    p = start.predictor.proba(z)
    assert start.iterations == 0 and start.kind == "vgp"
    assert p[y].mean() > 0.7 and p[~y].mean() < 0.3
    far = np.abs(z[:, 0] - 0.5) > 0.15
    assert ((p > 0.5) == y)[far].mean() > 0.95


def test_points_too_close_for_float32_are_fitted_in_float64(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import surrogate.models as models

    dtypes: list[torch.dtype] = []
    trained = models._trained

    def recording(*args: object) -> object:
        dtypes.append(args[-1])  # type: ignore[arg-type]
        return trained(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(models, "_trained", recording)
    v = np.random.default_rng(0).random(40)
    z = np.column_stack([np.zeros(40), v])  # one input on a line: inducing points crowd it
    fit = fit_classifier(z, v > 0.8, seed=0, max_iters=60)
    assert dtypes == [torch.float32, torch.float64]
    assert fit.kind == "vgp" and fit.predictor.proba(np.array([[0.0, 0.95]]))[0] > 0.5

"""Additive kernel terms: which decisions get one, what a fit with them learns, and that a warm
start never crosses from one kernel to another."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.additive import term_groups
from surrogate.domains import CategoricalDomain, ContinuousDomain
from surrogate.encoding import SpaceEncoder
from surrogate.models import fit_classifier

SPACE = {
    "#dir": CategoricalDomain(["top", "front", "left"]),
    "#pose": ContinuousDomain([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
}


def _placements(n: int, seed: int) -> tuple[SpaceEncoder, np.ndarray, np.ndarray]:
    """The top grasp fails wherever it places; the others where x < 0.4."""
    rng = np.random.default_rng(seed)
    encoder = SpaceEncoder(SPACE)
    points = [{"#dir": ["top", "front", "left"][i % 3], "#pose": rng.random(3)} for i in range(n)]
    ok = [p["#dir"] != "top" and p["#pose"][0] > 0.4 for p in points]
    xs = [{"#dir": p["#dir"], "#pose": p["#pose"].tolist()} for p in points]
    return encoder, encoder.encode_points(xs), np.asarray(ok)


def test_each_mode_names_its_decisions_columns() -> None:
    encoder = SpaceEncoder(SPACE)
    assert term_groups(encoder, "none") == ()
    assert term_groups(encoder, "choices") == ((0, 1, 2),)
    assert term_groups(encoder, "decisions") == ((0, 1, 2), (3, 4, 5))
    alone = SpaceEncoder({"#dir": SPACE["#dir"]})
    assert term_groups(alone, "decisions") == ()  # one decision: its term would be the kernel
    with pytest.raises(ValueError, match="not one of"):
        term_groups(encoder, "all")


def test_a_fit_with_terms_learns_what_one_decision_alone_decides() -> None:
    encoder, z, y = _placements(30, 0)
    fit = fit_classifier(z, y, seed=0, groups=term_groups(encoder, "choices"))
    assert len(fit.predictor.terms) == 1 and fit.train_accuracy > 0.9
    rng = np.random.default_rng(1)
    top = [{"#dir": "top", "#pose": rng.random(3).tolist()} for _ in range(100)]
    front = [{"#dir": "front", "#pose": [0.8, *rng.random(2).tolist()]} for _ in range(100)]
    assert fit.predictor.proba(encoder.encode_points(top)).mean() < 0.2
    assert fit.predictor.proba(encoder.encode_points(front)).mean() > 0.7
    assert np.all(fit.predictor.uncertainty(encoder.encode_points(top)) <= 1.0)


def test_a_warm_start_from_another_kernel_starts_cold() -> None:
    encoder, z, y = _placements(24, 2)
    plain = fit_classifier(z, y, seed=0)
    groups = term_groups(encoder, "decisions")
    crossed = fit_classifier(z, y, seed=0, warm=plain, groups=groups)
    cold = fit_classifier(z, y, seed=0, groups=groups)
    assert crossed.iterations == cold.iterations
    np.testing.assert_allclose(crossed.predictor.a, cold.predictor.a)
    again = fit_classifier(z, y, seed=0, warm=cold, groups=groups)
    assert len(again.predictor.terms) == 2

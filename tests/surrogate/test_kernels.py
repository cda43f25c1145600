"""The NumPy kernels, computed in place, give the textbook expressions' values exactly."""

from __future__ import annotations

import numpy as np

from surrogate.kernels import matern52, squared_distances
from surrogate.predictors import _mass


def test_squared_distances_and_matern52_are_their_formulas() -> None:
    rng = np.random.default_rng(5)
    a, b = rng.random((40, 6)), rng.random((30, 6))
    ell, scale = rng.uniform(0.1, 2.0, 6), 1.7
    d2 = np.maximum((a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T), 0.0)
    np.testing.assert_array_equal(squared_distances(a, b), d2)
    np.testing.assert_allclose(d2, ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1), atol=1e-12)
    r = np.sqrt(squared_distances(a / ell, b / ell))
    k = scale * (1.0 + np.sqrt(5.0) * r + (5.0 / 3.0) * r**2) * np.exp(-np.sqrt(5.0) * r)
    np.testing.assert_array_equal(matern52(a, b, ell, scale), k)
    similarity = np.exp(-0.5 * squared_distances(a, b) / (0.1**2 * 6)).sum(axis=1)
    np.testing.assert_array_equal(_mass(a, b, 0.1), similarity)

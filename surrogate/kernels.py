"""NumPy kernel evaluation for cached predictors (no autograd, thread-safe, batch-friendly)."""

from __future__ import annotations

import numpy as np

SQRT5 = np.sqrt(5.0)


def squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`(n, m)` squared Euclidean distances between rows of `a (n, D)` and `b (m, D)`, by one
    matrix product (no (n, m, D) array), clipped at 0 against rounding."""
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T)
    return np.maximum(d2, 0.0)


def matern52(
    x: np.ndarray, z: np.ndarray, lengthscale: np.ndarray, outputscale: float
) -> np.ndarray:
    """ARD Matern 5/2 between rows of `x (n, D)` and `z (m, D)` -> `(n, m)`."""
    r = np.sqrt(squared_distances(x / lengthscale, z / lengthscale))
    return outputscale * (1.0 + SQRT5 * r + (5.0 / 3.0) * r**2) * np.exp(-SQRT5 * r)

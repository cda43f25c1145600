"""NumPy kernel evaluation for cached predictors (no autograd, thread-safe, batch-friendly)."""

from __future__ import annotations

import numpy as np

SQRT5 = np.sqrt(5.0)


def matern52(
    x: np.ndarray, z: np.ndarray, lengthscale: np.ndarray, outputscale: float
) -> np.ndarray:
    """ARD Matern 5/2 between rows of `x (n, D)` and `z (m, D)` -> `(n, m)`."""
    xs = x / lengthscale
    zs = z / lengthscale
    d2 = (xs**2).sum(1)[:, None] + (zs**2).sum(1)[None, :] - 2.0 * xs @ zs.T
    r = np.sqrt(np.maximum(d2, 0.0))
    return outputscale * (1.0 + SQRT5 * r + (5.0 / 3.0) * r**2) * np.exp(-SQRT5 * r)

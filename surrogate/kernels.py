"""NumPy kernel evaluation for cached predictors (no autograd, thread-safe, batch-friendly)."""

from __future__ import annotations

import numpy as np

SQRT5 = np.sqrt(5.0)


def squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`(n, m)` squared Euclidean distances between rows of `a (n, D)` and `b (m, D)`, by one
    matrix product (no (n, m, D) array), clipped at 0 against rounding. The `(n, m)` steps are
    taken in place (in the order `|a|^2 + |b|^2 - 2 a.b`): a suggestion computes thousands of
    these, and fresh arrays for each step cost more than the arithmetic."""
    twice = a @ b.T
    twice *= 2.0
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :]
    d2 -= twice
    return np.maximum(d2, 0.0, out=d2)


def matern52(
    x: np.ndarray, z: np.ndarray, lengthscale: np.ndarray, outputscale: float
) -> np.ndarray:
    """ARD Matern 5/2 between rows of `x (n, D)` and `z (m, D)` -> `(n, m)`."""
    r = np.sqrt(squared_distances(x / lengthscale, z / lengthscale))
    # outputscale (1 + sqrt5 r + 5/3 r^2) exp(-sqrt5 r), step by step in place
    k = r * SQRT5
    k += 1.0
    square = r * r
    square *= 5.0 / 3.0
    k += square
    k *= outputscale
    r *= -SQRT5
    k *= np.exp(r, out=r)
    return k

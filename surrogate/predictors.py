"""Frozen NumPy predictors of P(feasible) on encoded inputs `Z in [0, 1]^D`.

Each holds the cached predictive terms of one fit (or the stated prior's points), so that
scoring a whole NSGA-II population is a few matrix products: no autograd, no Python loop per
point, safe to share between threads. Kept apart from the fitting code (`surrogate.models`) so
that a planner, which only loads served snapshots, never imports torch or gpytorch.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import ndtr

from surrogate.kernels import matern52, squared_distances

JITTER = 1e-6


class FeasibilityPredictor(Protocol):
    """Anything that maps GP inputs `(n, D)` to P(feasible) `(n,)`, and says how unsure it is.

    `uncertainty` is the posterior standard deviation of the latent function relative to its
    prior one, in [0, 1]: 1 where no data bears on the point (P(feasible) there is the model's
    extrapolation), near 0 where data pins it down. One scale for every kind, so that a picture
    can mark the unsure regions of any model with one threshold. Each row's answer depends on
    that row alone (`surrogate.acquisition.MPF` stacks the rows of several terms in one call).
    """

    def proba(self, z: np.ndarray) -> np.ndarray: ...

    def uncertainty(self, z: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class PriorPredictor:
    """The stated prior for a type with one class only or fewer than MIN_POINTS points.

    p(x) = 0.5 + weight (max_j k(x, feasible_j) - max_j k(x, infeasible_j)), with a squared
    exponential k of lengthscale `lengthscale * sqrt(D)`: no opinion far from any data, low
    next to a known infeasible point, high next to a known feasible one.

    With `strength` s > 0 the points are counted instead (`counted`): p(x) = (s / 2 + A) /
    (s + A + B), A and B the sums of k(x, .) over the feasible and the infeasible points, a
    Beta prior of s pseudo-points updated by kernel-weighted counts. Evidence then grows with
    the number of points: the nearest-point form rates a choice that failed once as low as one
    that failed twenty times (0.05 both), the counted one 1/3 against 1/21 (s = 2).
    """

    feasible: np.ndarray  # (a, D)
    infeasible: np.ndarray  # (b, D)
    weight: float = 0.45  # how far the prior moves P(feasible) away from 0.5 at a point
    lengthscale: float = 0.1  # its reach in the unit cube, per sqrt(D)
    strength: float = 0.0

    def proba(self, z: np.ndarray) -> np.ndarray:
        ell, c = self.lengthscale, 0.5
        if self.strength > 0:
            up, down = _mass(z, self.feasible, ell), _mass(z, self.infeasible, ell)
            return (self.strength * c + up) / (self.strength + up + down)
        up, down = _reach(z, self.feasible, ell), _reach(z, self.infeasible, ell)
        return c + 2 * self.weight * ((1.0 - c) * up - c * down)

    def counted(
        self,
        strength: float,
        feasible: np.ndarray | None = None,
        infeasible: np.ndarray | None = None,
    ) -> PriorPredictor:
        """This prior in the counting form of `strength` pseudo-points, with `feasible` `(a, D)`
        and `infeasible` `(b, D)` more points joined to its own."""

        def joined(own: np.ndarray, extra: np.ndarray | None) -> np.ndarray:
            return own if extra is None or not len(extra) else np.vstack([own, extra])

        return dataclasses.replace(
            self,
            strength=strength,
            feasible=joined(self.feasible, feasible),
            infeasible=joined(self.infeasible, infeasible),
        )

    def uncertainty(self, z: np.ndarray) -> np.ndarray:
        """sqrt(1 - k^2) for the largest similarity k to any point: the posterior sd of a
        unit-variance GP with the prior's kernel, given the nearest point alone (noise-free).
        Conditioning on every point could only lower it: an upper bound, 1 far from them all."""
        points = np.vstack([self.feasible, self.infeasible])
        return _unexplained(_nearest_reach(z, points, self.lengthscale))


def same_rows(block: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """`(n, k)` whether each row of `block` `(n, w)` is each of `rows` `(k, w)`: categorical
    choices are table rows, compared exactly up to float noise."""
    return np.abs(block[:, None, :] - rows[None, :, :]).max(axis=-1) < 1e-9


def _reach(z: np.ndarray, points: np.ndarray, lengthscale: float) -> np.ndarray:
    """`(n,)` the largest squared-exponential similarity of each row of `z` to `points`, with
    lengthscale `lengthscale * sqrt(D)`; 0 with no points."""
    if len(points) == 0:
        return np.zeros(len(z))
    # The largest similarity is the nearest point's: one exp per row, not one per pair, on the
    # path of every guided suggestion.
    nearest = squared_distances(z, points).min(axis=1)
    return np.exp(-0.5 * nearest / ((lengthscale**2) * z.shape[1]))


def _mass(z: np.ndarray, points: np.ndarray, lengthscale: float) -> np.ndarray:
    """`(n,)` the summed squared-exponential similarity of each row of `z` to `points`, with
    lengthscale `lengthscale * sqrt(D)`; 0 with no points."""
    if len(points) == 0:
        return np.zeros(len(z))
    scale = (lengthscale**2) * z.shape[1]
    similarity = squared_distances(z, points)
    similarity *= -0.5
    similarity /= scale
    return np.exp(similarity, out=similarity).sum(axis=1)


def _nearest_reach(z: np.ndarray, points: np.ndarray, lengthscale: float) -> np.ndarray:
    """`_reach` through a k-d tree: the largest similarity is the nearest point's, and a tree
    finds it without the (n, points) matrix of distances a large type's prior would need."""
    if len(points) == 0:
        return np.zeros(len(z))
    distance, _ = cKDTree(points).query(z)
    return np.exp(-0.5 * distance**2 / ((lengthscale**2) * z.shape[1]))


def _unexplained(reach: np.ndarray) -> np.ndarray:
    return np.sqrt(np.clip(1.0 - reach**2, 0.0, 1.0))


@dataclass(frozen=True)
class RecentPoints:
    """A fitted predictor plus the points that arrived after its fit, as the stated prior
    weighs them: P(feasible) falls next to a new infeasible point and rises next to a new
    feasible one, until the next fit takes them in. Rollouts are cheaper than fits, so without
    this a planner keeps being sent back to where it has just failed."""

    base: FeasibilityPredictor
    feasible: np.ndarray  # (a, D)
    infeasible: np.ndarray  # (b, D)
    weight: float = 0.5  # how far a point moves P(feasible) toward its label, at the point
    lengthscale: float = 0.05  # its reach per sqrt(D): half the prior's, since a fit will follow

    def proba(self, z: np.ndarray) -> np.ndarray:
        p = self.base.proba(z)
        up = self.weight * _reach(z, self.feasible, self.lengthscale)
        down = self.weight * _reach(z, self.infeasible, self.lengthscale)
        return p + (1.0 - p) * up * (1.0 - down) - p * down * (1.0 - up)

    def uncertainty(self, z: np.ndarray) -> np.ndarray:
        """The fit's, lowered next to the new points as the prior's bound has it (with this
        wrapper's reach): more data can only lower a GP's posterior variance."""
        points = np.vstack([self.feasible, self.infeasible])
        near = _unexplained(_nearest_reach(z, points, self.lengthscale))
        return np.minimum(self.base.uncertainty(z), near)


@dataclass(frozen=True)
class UnseenChoices:
    """A fit answers for the choices of its categorical variables that its points hold; for a
    choice that none of them has (a grasp the earlier tasks never tried), `prior` answers: the
    fit's value there is an extrapolation to the type's base rate, which would rate an untried
    grasp as badly as the ones that failed."""

    base: FeasibilityPredictor
    prior: FeasibilityPredictor
    seen: tuple[tuple[slice, np.ndarray], ...]  # per categorical: its columns, the seen rows (k, w)

    def _unseen(self, z: np.ndarray) -> np.ndarray:
        unseen = np.zeros(len(z), dtype=bool)
        for columns, rows in self.seen:
            unseen |= ~same_rows(z[:, columns], rows).any(axis=1)
        return unseen

    def _answer(self, z: np.ndarray, of_base: Any, of_prior: Any) -> np.ndarray:
        """`of_base(z)`, with `of_prior` answering for the rows of untried choices (asked of
        those rows only: the prior's cost grows with the type's points)."""
        values = of_base(z)
        unseen = self._unseen(z)
        if not unseen.any():
            return values
        values = np.array(values, dtype=float)
        values[unseen] = of_prior(z[unseen])
        return values

    def proba(self, z: np.ndarray) -> np.ndarray:
        return self._answer(z, self.base.proba, self.prior.proba)

    def uncertainty(self, z: np.ndarray) -> np.ndarray:
        """The prior's where it answers (an untried choice), the fit's elsewhere."""
        return self._answer(z, self.base.uncertainty, self.prior.uncertainty)


@dataclass(frozen=True)
class VGPPredictor:
    """Cached predictive terms of a whitened variational GP: mean = c + K_xz a,
    var = k_xx + rowsum((K_xz B) * K_xz), P(feasible) = Phi(mean / sqrt(1 + var))."""

    inducing: np.ndarray  # (m, D)
    lengthscale: np.ndarray  # (D,)
    outputscale: float
    constant: float
    a: np.ndarray  # (m,) = L^-T m_v
    b: np.ndarray  # (m, m) = L^-T (S - I) L^-1

    def latent(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        kxz = matern52(z, self.inducing, self.lengthscale, self.outputscale)
        mean = self.constant + kxz @ self.a
        var = self.outputscale + JITTER + ((kxz @ self.b) * kxz).sum(1)
        return mean, np.maximum(var, 1e-12)

    def proba(self, z: np.ndarray) -> np.ndarray:
        mean, var = self.latent(z)
        return ndtr(mean / np.sqrt(1.0 + var))

    def uncertainty(self, z: np.ndarray) -> np.ndarray:
        """The latent posterior sd over the prior's (outputscale): 1 away from the inducing
        points, lower where the variational posterior has learnt from data."""
        _, var = self.latent(z)
        return np.sqrt(np.clip(var / (self.outputscale + JITTER), 0.0, 1.0))


@dataclass(frozen=True)
class RegressionPredictor:
    """Cached exact-GP posterior: mean = c + K_xX alpha, var = k_xx - |L^-1 K_Xx|^2 (latent f),
    in the units of the training targets."""

    train: np.ndarray  # (n, D)
    lengthscale: np.ndarray
    outputscale: float
    constant: float
    noise: float
    alpha: np.ndarray  # (n,)
    chol_inv: np.ndarray  # (n, n) = L^-1, L = chol(K + noise I)
    y_shift: float = 0.0
    y_scale: float = 1.0

    def predict(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean and standard deviation of f at `z (n, D)`."""
        kxn = matern52(z, self.train, self.lengthscale, self.outputscale)
        mean = self.constant + kxn @ self.alpha
        w = kxn @ self.chol_inv.T
        var = np.maximum(self.outputscale - (w * w).sum(1), 1e-12)
        return self.y_shift + self.y_scale * mean, self.y_scale * np.sqrt(var)


@dataclass(frozen=True)
class LabelRegressionPredictor:
    """The authors' variant: GP regression on +1 (feasible) / -1 labels, PoF = Phi(mu / sigma)."""

    regression: RegressionPredictor

    def proba(self, z: np.ndarray) -> np.ndarray:
        mean, std = self.regression.predict(z)
        return ndtr(mean / std)

    def uncertainty(self, z: np.ndarray) -> np.ndarray:
        """The latent posterior sd over the prior's (the label scale is fixed at 1 here)."""
        r = self.regression
        _, std = r.predict(z)
        return np.clip(std / (r.y_scale * np.sqrt(r.outputscale)), 0.0, 1.0)

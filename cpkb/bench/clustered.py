"""Intervals that resample targets: a suite's runs are clustered by target, not independent.

A kind of a generated suite pools a few targets, each run on many seeds; the seeds of one
target share its difficulty, so resampling (target, seed) pairs as if they were independent
draws an interval as if there were many targets, too narrow when the targets differ. The
clustered bootstrap resamples the targets (with replacement), then each picked target's seeds
within it (a target picked twice gets two resamples), and pools the runs: with identical
targets it reads as the pairwise interval, and one target that dominates the mean widens it.

Each target holds the runs of two arms, a baseline `a` and a method `b`; `paired`: the arms'
runs of a target are of the same seeds in the same order and are resampled together.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

RESAMPLES = 2000

Target = tuple[np.ndarray, np.ndarray]
"""The baseline's and the method's rollouts on one target."""


def resampled_means(
    targets: Sequence[Target], *, paired: bool, resamples: int = RESAMPLES
) -> tuple[np.ndarray, np.ndarray]:
    """Per resample, the pooled mean of the baseline's runs and of the method's (seeded: the
    same result set gives the same interval)."""
    if paired and any(len(a) != len(b) for a, b in targets):
        raise ValueError("paired arms need the same seeds on every target")
    rng = np.random.default_rng(0)
    count = len(targets)
    picks = rng.integers(0, count, (resamples, count))
    sums = np.zeros((2, resamples))
    runs = np.zeros((2, resamples))
    for index, (a, b) in enumerate(targets):
        chosen = picks == index  # (resample, slot): where this target was picked
        seeds_a = rng.integers(0, len(a), (resamples, count, len(a)))
        seeds_b = seeds_a if paired else rng.integers(0, len(b), (resamples, count, len(b)))
        for arm, (values, seeds) in enumerate(((a, seeds_a), (b, seeds_b))):
            sums[arm] += (values[seeds].sum(axis=2) * chosen).sum(axis=1)
            runs[arm] += chosen.sum(axis=1) * len(values)
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums[0] / runs[0], sums[1] / runs[1]


def reduction_ci(targets: Sequence[Target], *, paired: bool = False) -> tuple[float, float] | None:
    """The clustered 95 % interval of the method's reduction of the mean against the
    baseline's, in percent of the baseline's (positive: fewer); None with fewer than two
    targets (then only the seeds vary: the pairwise interval says it)."""
    if len(targets) < 2 or any(len(a) == 0 or len(b) == 0 for a, b in targets):
        return None
    base, method = resampled_means(targets, paired=paired)
    reductions = 100.0 * (base - method) / np.where(base > 0, base, np.nan)
    low, high = np.nanpercentile(reductions, [2.5, 97.5])
    return float(low), float(high)


def ratio_ci(targets: Sequence[Target], *, paired: bool = True) -> tuple[float, float] | None:
    """The clustered 95 % interval of mean(method) / mean(baseline); None as `reduction_ci`."""
    if len(targets) < 2 or any(len(a) == 0 or len(b) == 0 for a, b in targets):
        return None
    base, method = resampled_means(targets, paired=paired)
    low, high = np.nanpercentile(method / np.where(base > 0, base, np.nan), [2.5, 97.5])
    return float(low), float(high)


def beats(targets: Sequence[Target]) -> tuple[int, int]:
    """On how many targets the method's mean is below the baseline's, of how many."""
    return sum(float(np.mean(b)) < float(np.mean(a)) for a, b in targets), len(targets)

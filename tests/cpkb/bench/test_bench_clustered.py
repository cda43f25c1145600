"""The clustered bootstrap (targets resampled, then seeds within) on result sets with a known
answer: identical targets read as the pairwise interval, one dominating target widens it."""

from __future__ import annotations

import numpy as np
import pytest

from cpkb.bench import clustered
from cpkb.bench.stats import _reduction_ci, summarize_by_kind
from cpkb.bench.together import ratio_ci

BASE = np.array([12.0, 30, 45, 80, 150, 9, 60, 400])
METHOD = np.array([5.0, 12, 30, 8, 60, 4, 20, 90])


def _close(ours: tuple[float, float], theirs: tuple[float, float], share: float) -> None:
    """Both bounds within `share` of the pairwise interval's width (bootstrap noise)."""
    width = theirs[1] - theirs[0]
    assert ours[0] == pytest.approx(theirs[0], abs=share * width)
    assert ours[1] == pytest.approx(theirs[1], abs=share * width)


def test_identical_targets_read_as_the_pairwise_interval():
    """Resampling six copies of one target changes nothing but the seeds drawn."""
    targets = [(BASE, METHOD)] * 6
    pairwise = _reduction_ci(np.tile(METHOD, 6), np.tile(BASE, 6))
    _close(clustered.reduction_ci(targets), pairwise, 0.1)
    _close(clustered.ratio_ci(targets), ratio_ci(np.tile(BASE, 6), np.tile(METHOD, 6)), 0.1)


def test_one_dominating_target_widens_the_interval_to_take_in_no_reduction():
    """Four targets where the method equals the baseline, one where the baseline takes 1000
    rollouts and the method 10: the mean's reduction rests on that one target, and a
    resample without it (a third of them) reduces nothing."""
    even = (np.full(8, 20.0), np.full(8, 20.0))
    dominating = (np.full(8, 1000.0), np.full(8, 10.0))
    targets = [even] * 4 + [dominating]
    pooled = [np.concatenate([t[arm] for t in targets]) for arm in (0, 1)]
    low, high = clustered.reduction_ci(targets)
    pair_low, pair_high = _reduction_ci(pooled[1], pooled[0])
    assert low == pytest.approx(0.0, abs=1e-9) and high > pair_high
    assert pair_low > 80  # pairs resampled as if independent: a tight, high interval
    assert clustered.beats(targets) == (1, 5)


def test_paired_arms_resample_each_seed_with_its_pair():
    """Where the method takes the baseline's rollouts less one on every seed, each paired
    resample has a ratio just under 1; unpaired resamples spread on both sides of it."""
    targets = [(BASE + k, BASE + k - 1) for k in range(5)]
    low, high = clustered.ratio_ci(targets, paired=True)
    assert 0.95 < low <= high < 1.0
    unpaired_low, unpaired_high = clustered.ratio_ci(targets, paired=False)
    assert unpaired_low < 0.9 and unpaired_high > 1.1
    with pytest.raises(ValueError, match="same seeds"):
        clustered.ratio_ci([(BASE, METHOD[:3])] * 2, paired=True)


def test_one_target_has_no_clustered_interval():
    assert clustered.reduction_ci([(BASE, METHOD)]) is None


def test_a_kinds_row_and_the_overall_row_carry_the_clustered_interval():
    records = [
        {"task": f"ws{w}/{kind}.yaml", "method": method, "seed": s, "solved": True, "wall_s": 1.0}
        | {"rollouts": int(rollouts)}
        for w in range(3)
        for kind in ("desk", "pack")
        for method, values in (("quasi-random-restarts", BASE), ("cp-bo", METHOD))
        for s, rollouts in enumerate(values)
    ]
    kinds = {f"ws{w}/{kind}.yaml": kind for w in range(3) for kind in ("desk", "pack")}
    rows = {(r.task, r.method): r for r in summarize_by_kind(records, kinds)}
    for kind, targets in (("desk", 3), ("pack", 3), ("all", 6)):
        row = rows[(kind, "cp-bo")]
        assert row.targets == targets and row.beats == (targets, targets)
        expected = clustered.reduction_ci([(BASE, METHOD)] * targets)
        assert row.reduction_ci_targets == pytest.approx(expected)
        assert rows[(kind, "quasi-random-restarts")].reduction_ci_targets is None

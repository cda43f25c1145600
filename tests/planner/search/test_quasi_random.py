"""The Voronoi sampler keeps the farthest candidate from the siblings; choices not repeated."""

from __future__ import annotations

import numpy as np
import pytest

from contract.models import CategoricalDomain, ContinuousDomain
from planner.search.samplers.quasi_random import untried_choice, voronoi_point


def test_voronoi_keeps_the_farthest_of_ten_per_dim_candidates():
    domain = ContinuousDomain(low=[0.0, -2.0], high=[1.0, 2.0])
    siblings = [[0.1, -1.5], [0.9, 1.5], [0.5, 0.0]]
    chosen = voronoi_point(domain, siblings, np.random.default_rng(7))
    candidates = np.random.default_rng(7).random((20, 2))
    scaled = (np.asarray(siblings) - [0.0, -2.0]) / [1.0, 4.0]
    gaps = np.linalg.norm(candidates[:, None] - scaled[None], axis=2).min(axis=1)
    expected = candidates[gaps.argmax()] * [1.0, 4.0] + [0.0, -2.0]
    assert chosen == pytest.approx(expected.tolist())
    assert gaps.max() > np.median(gaps)


@pytest.mark.parametrize("seed", range(5))
def test_voronoi_fills_gaps_better_than_uniform(seed):
    domain = ContinuousDomain(low=[0.0], high=[1.0])
    rng = np.random.default_rng(seed)
    points: list[list[float]] = []
    for _ in range(20):
        points.append(voronoi_point(domain, points, rng))
    voronoi_gap = np.diff(np.sort([0.0, *[p[0] for p in points], 1.0])).max()
    uniform_gap = np.diff(np.sort([0.0, *np.random.default_rng(seed).random(20), 1.0])).max()
    assert voronoi_gap < 0.1 < uniform_gap


def test_categorical_choices_are_drawn_without_replacement():
    domain = CategoricalDomain(choices=["front", "right", "top", "back", "left"])
    rng = np.random.default_rng(1)
    tried: list[str] = []
    for _ in range(5):
        tried.append(untried_choice(domain, tried, rng))
    assert sorted(tried) == sorted(domain.choices)
    with pytest.raises(ValueError, match="every choice"):
        untried_choice(domain, tried, rng)

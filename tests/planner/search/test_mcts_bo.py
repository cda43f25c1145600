"""MCTS-BO: GP-UCB on the children's rewards once they differ, space filling before."""

from __future__ import annotations

import numpy as np
import pytest

from contract.models import ContinuousDomain
from planner.search.samplers.base import SampleContext
from planner.search.samplers.mcts_bo import MctsBoSampler
from planner.skeleton import DecisionVar, OperatorCall

DOMAIN = ContinuousDomain(low=[0.0, 0.0], high=[1.0, 1.0])
VAR = DecisionVar(
    "#pose1", "#pose", DOMAIN, OperatorCall("Sample-pose", ("body", "r"), ("#pose1",))
)


def context(siblings, rewards, seed=0) -> SampleContext:
    return SampleContext(
        var=VAR,
        path={},
        siblings=tuple(siblings),
        sibling_rewards=tuple(rewards),
        sibling_visits=tuple(1 for _ in siblings),
        depth=0,
        rollout=len(siblings) + 1,
        rng=np.random.default_rng(seed),
    )


def test_equal_rewards_fall_back_to_space_filling():
    sampler = MctsBoSampler()
    value = sampler.propose(context([[0.1, 0.1], [0.9, 0.9]], [0.025, 0.025]))
    assert sampler.unguided == 1 and sampler.guided == 0
    assert all(0.0 <= v <= 1.0 for v in value)


@pytest.mark.slow
def test_ucb_goes_where_the_rewards_are_high_and_is_seeded():
    rng = np.random.default_rng(4)
    siblings = rng.random((12, 2)).tolist()
    # The reward grows toward the corner (1, 1).
    rewards = [0.1 * (x + y) / 2 for x, y in siblings]
    first = MctsBoSampler(beta=0.1).propose(context(siblings, rewards, seed=1))
    again = MctsBoSampler(beta=0.1).propose(context(siblings, rewards, seed=1))
    assert first == again
    assert sum(first) > 1.2, first
    assert first not in siblings


def graded_context(siblings, rewards, scores, seed=0) -> SampleContext:
    base = context(siblings, rewards, seed)
    return SampleContext(**{**base.__dict__, "sibling_scores": tuple(scores)})


def test_graded_scores_guide_where_the_rewards_are_all_equal():
    rng = np.random.default_rng(4)
    siblings = rng.random((12, 2)).tolist()
    rewards = [0.025] * len(siblings)  # every child failed at the same check
    # ... but came closer to passing it toward the corner (1, 1), within the check's band.
    scores = [0.025 + 0.008 * (x + y) / 2 for x, y in siblings]
    sampler = MctsBoSampler(beta=0.1)
    value = sampler.propose(graded_context(siblings, rewards, scores, seed=1))
    assert sampler.guided == 1 and sampler.unguided == 0
    assert sum(value) > 1.2, value


def test_ungraded_sampler_ignores_the_scores():
    siblings = [[0.1, 0.1], [0.9, 0.9]]
    sampler = MctsBoSampler(graded=False)
    sampler.propose(graded_context(siblings, [0.025, 0.025], [0.026, 0.030]))
    assert sampler.unguided == 1 and sampler.guided == 0


def test_a_tree_without_scores_falls_back_to_the_rewards():
    rng = np.random.default_rng(4)
    siblings = rng.random((6, 2)).tolist()
    rewards = [0.1 * x for x, _ in siblings]
    sampler = MctsBoSampler()
    sampler.propose(context(siblings, rewards))  # sibling_scores is None
    assert sampler.guided == 1


def test_min_children_defers_the_gp():
    siblings = [[0.1, 0.1], [0.5, 0.5], [0.9, 0.9]]
    scores = [0.02, 0.03, 0.04]
    sampler = MctsBoSampler(min_children=4)
    sampler.propose(graded_context(siblings, [0.02] * 3, scores))
    assert sampler.unguided == 1
    sampler.propose(graded_context([*siblings, [0.3, 0.7]], [0.02] * 4, [*scores, 0.05]))
    assert sampler.guided == 1

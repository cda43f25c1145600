"""MCTS-BO: GP-UCB on the children's rewards once they differ, space filling before."""

from __future__ import annotations

import numpy as np

from client.models import ContinuousDomain
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

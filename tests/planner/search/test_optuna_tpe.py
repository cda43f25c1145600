"""The Optuna TPE peer sampler: valid values, seeded, and it learns from the constraint."""

from __future__ import annotations

import numpy as np

from contract.models import CategoricalDomain, ContinuousDomain
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers import make, methods
from planner.search.samplers.base import SampleContext
from planner.search.samplers.optuna_tpe import OptunaTpeSampler
from planner.skeleton import DecisionVar, OperatorCall

PRODUCER = OperatorCall("Sample-pose", ("body", "region2"), ("#pose12",))
N_LAYERS = 4
FAILED_HERE = 0.1 * 1 / N_LAYERS  # failed its own transition at decision index 0
PASSED = 0.1 * 3 / N_LAYERS  # passed it, failed one layer later


def _ctx(var: DecisionVar, siblings: list, rewards: list[float], rng) -> SampleContext:
    return SampleContext(
        var=var,
        path={},
        siblings=tuple(siblings),
        sibling_rewards=tuple(rewards),
        sibling_visits=tuple(1 for _ in siblings),
        depth=0,
        rollout=len(siblings) + 1,
        rng=rng,
    )


def test_registered_as_optuna_tpe() -> None:
    assert "optuna-tpe" in methods()
    sampler = make("optuna-tpe", seed=3, world=analytic_world("desk"))
    assert sampler.name == "optuna-tpe"


def test_proposals_concentrate_where_the_transition_passed() -> None:
    var = DecisionVar(
        "#pose12", "#pose", ContinuousDomain(low=[0.0, 0.0], high=[1.0, 2.0]), PRODUCER
    )
    sampler = OptunaTpeSampler(seed=0, n_layers=N_LAYERS)
    rng = np.random.default_rng(0)
    values: list[list[float]] = []
    for _ in range(60):
        rewards = [PASSED if v[0] > 0.7 else FAILED_HERE for v in values]
        value = sampler.propose(_ctx(var, values, rewards, rng))
        assert len(value) == 2 and 0 <= value[0] <= 1 and 0 <= value[1] <= 2
        values.append(value)
    late = np.array([v[0] for v in values[30:]])
    # Uniform sampling would put 30% of them there.
    assert np.mean(late > 0.7) >= 0.6


def test_categorical_never_repeats_a_tried_choice() -> None:
    var = DecisionVar("#dir1", "#dir", CategoricalDomain(choices=list("abcde")), PRODUCER)
    sampler = OptunaTpeSampler(seed=1, n_layers=N_LAYERS)
    rng = np.random.default_rng(1)
    tried: list[str] = []
    for _ in range(5):
        choice = sampler.propose(_ctx(var, tried, [FAILED_HERE] * len(tried), rng))
        assert choice in "abcde" and choice not in tried
        tried.append(choice)
    assert sorted(tried) == list("abcde")


def test_binds_the_analytic_desk_reproducibly() -> None:
    rollouts = []
    for _ in range(2):
        world = analytic_world("desk")
        sampler = make("optuna-tpe", seed=7, world=world)
        result = PWUCT(world, sampler, seed=7).run(2000)
        assert result.solved
        rollouts.append(result.rollouts)
    assert rollouts[0] == rollouts[1]

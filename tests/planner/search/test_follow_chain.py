"""A binding the sampler hands out (`Sampler.chain`) is the next rollout, whatever the tree."""

from __future__ import annotations

from contract.models import Value
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers.quasi_random import QuasiRandomSampler


class ChainAt(QuasiRandomSampler):
    """Quasi-random that hands out `binding` once, before rollout `at`."""

    def __init__(self, binding: dict[str, Value], at: int) -> None:
        super().__init__()
        self.binding, self.at, self.asked = binding, at, 0

    def chain(self) -> dict[str, Value] | None:
        self.asked += 1
        return self.binding if self.asked == self.at else None


def _solution(seed: int) -> dict[str, Value]:
    found = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=seed).run(2000)
    assert found.solved and found.bindings is not None
    return found.bindings


def test_the_handed_out_binding_is_the_next_rollout_and_opens_what_the_tree_lacks():
    binding = _solution(seed=1)
    alone = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=2).run(2000)
    at = 4
    assert alone.rollouts > at, "the run alone must not be solved by then"
    search = PWUCT(analytic_world("desk"), ChainAt(binding, at), seed=2)
    followed = search.run(2000)
    assert followed.solved and followed.rollouts == at
    assert followed.bindings == binding
    assert binding["#dir1"] in search.root.values


def test_a_failing_binding_costs_one_rollout_and_the_search_goes_on():
    binding = dict(_solution(seed=1))
    world = analytic_world("desk")
    for i in range(1000):  # a placement of the same grasp that fails
        pose = [((i * k * 0.6180339887) % 1.0) for k in (1, 2, 3)]
        outcome = world.transition(1, {**binding, "#pose12": pose}, None)
        if outcome.failed is not None:
            binding["#pose12"] = pose
            break
    sampler = ChainAt(binding, at=1)
    search = PWUCT(analytic_world("desk"), sampler, seed=2)
    result = search.run(2000)
    assert result.solved and result.rollouts > 1
    assert sampler.asked >= result.rollouts

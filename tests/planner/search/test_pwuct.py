"""The graded score: a failed check's `progress` reaches the sampler, inside the check's band,
and leaves the tree's rewards (and so every other sampler's search) as they were."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import pytest

from contract.models import Value
from planner.search import PWUCT
from planner.search.analytic import AnalyticWorld, analytic_world
from planner.search.samplers.base import SampleContext
from planner.search.samplers.quasi_random import QuasiRandomSampler
from planner.world import TransitionOutcome


class GradedWorld:
    """The analytic desk, whose failed shelf IK reports how close the placement came to the
    reachable disc as detail `progress` (as the PyBullet world does with residuals)."""

    def __init__(self) -> None:
        self.inner: AnalyticWorld = analytic_world("desk")
        self.name = "graded-desk"
        self.skeleton = self.inner.skeleton

    def initial_state(self) -> object:
        return None

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        outcome = self.inner.transition(index, bindings, state)
        failed = outcome.failed
        if failed is None or index != 1:
            return outcome
        x, y, _ = bindings["#pose12"]  # type: ignore[misc]
        progress = max(0.0, 1.0 - ((x - 0.65) ** 2 + (y - 0.35) ** 2) ** 0.5)
        graded = replace(failed, detail={"progress": progress})
        return replace(outcome, checks=(*outcome.checks[:-1], graded))


class Recording(QuasiRandomSampler):
    """Quasi-random, keeping every context it was given."""

    def __init__(self) -> None:
        super().__init__()
        self.contexts: list[SampleContext] = []

    def propose(self, ctx: SampleContext) -> Value:
        self.contexts.append(ctx)
        return super().propose(ctx)


def test_graded_scores_reach_the_sampler_within_the_failed_checks_band():
    sampler = Recording()
    PWUCT(GradedWorld(), sampler, seed=0).run(200)
    placements = [c for c in sampler.contexts if c.var.var == "#pose12" and len(c.siblings) > 3]
    assert placements
    band = 0.1 / 4 / 3  # one check of the 3 in the last of 4 layers
    seen_graded = False
    for ctx in placements:
        assert ctx.sibling_scores is not None
        assert len(ctx.sibling_scores) == len(ctx.sibling_rewards)
        for r, s in zip(ctx.sibling_rewards, ctx.sibling_scores, strict=True):
            assert r <= s < r + band or r > 1.0
        first_check = [
            s for r, s in zip(ctx.sibling_rewards, ctx.sibling_scores, strict=True) if r < 0.076
        ]
        if len(set(first_check)) > 1:
            seen_graded = True
    assert seen_graded, "children failing at the same check should score apart"


def test_a_passed_child_scores_the_best_below_it():
    search = PWUCT(GradedWorld(), QuasiRandomSampler(), seed=0)
    search.run(200)
    for child in search.root.children:
        if child.next is not None and child.next.children:
            assert child.score == pytest.approx(max(c.score for c in child.next.children))
            assert child.score >= child.reward


def test_grading_leaves_the_search_unchanged():
    """Quasi-random ignores the scores: it must take the very same rollouts either way."""
    graded = PWUCT(GradedWorld(), QuasiRandomSampler(), seed=5).run(500)
    plain = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=5).run(500)
    assert graded.rollouts == plain.rollouts
    assert graded.bindings == plain.bindings

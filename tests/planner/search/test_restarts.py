"""`search.restart_unit`: the tree is grown anew on Luby's schedule, rollouts count across
trees, a fresh tree's first child is sampled as a first child again, and only a sampler that
keeps its knowledge beyond the tree restarts."""

from __future__ import annotations

from collections.abc import Mapping

import pytest

from contract.models import Value
from planner.config import ConfigError, PlanConfig, SearchConfig, method_config
from planner.run import run_plan
from planner.search import PWUCT
from planner.search.analytic import AnalyticWorld, analytic_world
from planner.search.pwuct import luby
from planner.search.samplers.base import SampleContext
from planner.search.samplers.quasi_random import QuasiRandomSampler
from planner.world import CheckResult, TransitionOutcome


class Unplaceable:
    """The analytic desk with every placement moved out of the arm's reach: no run solves."""

    def __init__(self) -> None:
        self.inner: AnalyticWorld = analytic_world("desk")
        self.name = "unplaceable-desk"
        self.skeleton = self.inner.skeleton

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        if index == 1:
            bindings = {**bindings, "#pose12": (0.0, 0.0, 0.0)}
        return self.inner.transition(index, bindings, state)


class FirstChoices(QuasiRandomSampler):
    """Quasi-random, noting the rollout of every grasp opened at a root with no children; by
    default it claims to keep knowledge beyond the tree, as cp-bo does."""

    def __init__(self, keeps_knowledge: bool = True) -> None:
        super().__init__()
        self.keeps_knowledge = keeps_knowledge
        self.fresh_roots: list[int] = []

    def propose(self, ctx: SampleContext) -> Value:
        if ctx.depth == 0 and not ctx.siblings:
            self.fresh_roots.append(ctx.rollout)
        return super().propose(ctx)


def test_lubys_sequence():
    assert [luby(i) for i in range(1, 16)] == [1, 1, 2, 1, 1, 2, 4, 1, 1, 2, 1, 1, 2, 4, 8]
    with pytest.raises(ValueError, match="starts at 1"):
        luby(0)


def test_the_tree_restarts_on_lubys_schedule_and_rollouts_count_across_trees():
    sampler = FirstChoices()
    search = PWUCT(Unplaceable(), sampler, seed=3, config=SearchConfig(restart_unit=5))
    result = search.run(100)
    assert not result.solved
    assert result.rollouts == result.rollouts_spent == 100
    # Runs of 5 x (1, 1, 2, 1, 1, 2, 4, 1, 1, 2, 1, 1, 2): none after the budget's last rollout.
    assert sampler.fresh_roots == [1, 6, 11, 21, 26, 31, 41, 61, 66, 71, 81, 86, 91]
    assert result.restarts == 12
    assert search.root.visits == 10


def test_a_geometric_schedule_doubles_each_trees_allowance():
    sampler = FirstChoices()
    config = SearchConfig(restart_unit=5, restart_schedule="geometric")
    result = PWUCT(Unplaceable(), sampler, seed=3, config=config).run(100)
    assert sampler.fresh_roots == [1, 6, 16, 36, 76]  # trees of 5, 10, 20, 40 rollouts, then 80
    assert result.restarts == 4


def test_an_unknown_schedule_is_refused():
    with pytest.raises(ConfigError, match="luby, geometric"):
        PlanConfig().with_overrides({"search.restart_schedule": "fibonacci"})


@pytest.mark.parametrize(
    ("config", "keeps_knowledge"),
    [(SearchConfig(restart_unit=0), True), (SearchConfig(restart_unit=5), False)],
    ids=["no unit", "a sampler that keeps nothing"],
)
def test_one_tree_serves_the_whole_run(config: SearchConfig, keeps_knowledge: bool):
    sampler = FirstChoices(keeps_knowledge)
    result = PWUCT(Unplaceable(), sampler, seed=3, config=config).run(100)
    assert sampler.fresh_roots == [1]
    assert result.restarts == 0


def test_a_restarting_search_still_solves():
    result = PWUCT(
        analytic_world("desk"), FirstChoices(), seed=4, config=SearchConfig(restart_unit=2)
    ).run(2000)
    assert result.solved


def test_a_cp_bo_run_restarts_by_default_and_records_it(live_kb):
    assert PlanConfig().search.restart_unit > 0
    assert method_config("cp-bo-paper").search.restart_unit == 0
    config = PlanConfig().with_overrides({"search.restart_unit": 1})
    common = {"max_rollouts": 10, "kb_url": live_kb.url, "kb": live_kb.name, "config": config}
    result = run_plan(Unplaceable(), "cp-bo", 3, **common)
    assert not result.solved and result.knowledge.kb_errors == 0
    assert "tree restarted 6 times" in result.notes  # runs 1,1,2,1,1,2 of the 10 rollouts
    assert result.config["search"]["restart_unit"] == 1
    paper = run_plan(Unplaceable(), "cp-bo-paper", 3, **common)
    assert not any("restarted" in note for note in paper.notes)
    assert paper.config["search"]["restart_unit"] == 0
    plain = run_plan(Unplaceable(), "quasi-random", 3, max_rollouts=200)
    assert not any("restarted" in note for note in plain.notes)


class Attempts(Unplaceable):
    """The unplaceable desk, noting the attempt number of every pick (the first transition)."""

    def __init__(self) -> None:
        super().__init__()
        self.picks: list[int] = []

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        if index == 0:
            self.picks.append(attempt)
        return super().transition(index, bindings, state, attempt=attempt)


@pytest.mark.parametrize("redraws", [False, True])
def test_a_restarted_tree_draws_its_checks_afresh_only_with_restart_redraws(redraws):
    """With `restart_redraws` the picks of the k-th tree are attempts of their own, past every
    retry of the trees before (never a draw an earlier tree made); without it every tree's
    first pick of a grasp is attempt 0, the first tree's draw again."""
    world = Attempts()
    config = SearchConfig(restart_unit=5, restart_redraws=redraws, inconclusive_retries=2)
    result = PWUCT(world, FirstChoices(), seed=3, config=config).run(40)
    assert result.restarts >= 3 and not result.solved
    firsts = [a for a in world.picks if a % 3 == 0]
    if redraws:
        assert sorted(set(firsts)) == [3 * k for k in range(result.restarts + 1)]
    else:
        assert set(world.picks) == {0}


class LuckyLater(Unplaceable):
    """The analytic desk (placeable) whose picks find no IK, inconclusively, on every draw
    below attempt 4: the first tree's retries (attempts 1-3) never reach one that passes.
    `proven`: the failures are proofs instead (and no attempt passes)."""

    def __init__(self, proven: bool = False) -> None:
        super().__init__()
        self.proven = proven

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        outcome = self.inner.transition(index, bindings, state)
        if index == 0 and (attempt < 4 or self.proven):
            call = self.skeleton.transitions[0].calls[0]
            failed = CheckResult(call, False, "no IK", conclusive=self.proven)
            return TransitionOutcome((failed,))
        return outcome


@pytest.mark.parametrize("redraws", [False, True])
def test_a_tree_closed_by_unproven_failures_restarts_with_fresh_draws(redraws):
    """Every grasp fails inconclusively in the first tree, retries included: without
    `restart_redraws` the search ends there, exhausted; with it a fresh tree draws anew and
    solves. A tree closed by proofs alone still ends the search (`Unplaceable`)."""
    config = SearchConfig(restart_unit=64, restart_redraws=redraws, inconclusive_retries=3)
    result = PWUCT(LuckyLater(), FirstChoices(), seed=1, config=config).run(200)
    assert result.solved is redraws
    assert result.exhausted is not redraws
    assert result.restarts == (1 if redraws else 0)
    proven = PWUCT(LuckyLater(proven=True), FirstChoices(), seed=1, config=config).run(200)
    assert proven.exhausted and not proven.solved and proven.restarts == 0


def test_quasi_random_restarts_is_quasi_random_with_restarts_and_nothing_else():
    paper = PlanConfig().to_dict()
    strongest = method_config("quasi-random-restarts").to_dict()
    assert not paper["search"]["restart_without_knowledge"]
    assert strongest["search"].pop("restart_without_knowledge")
    paper["search"].pop("restart_without_knowledge")
    assert strongest == paper


def test_the_strongest_baseline_restarts_on_the_schedule_and_redraws_its_checks():
    """Quasi-random keeps nothing beyond its tree, yet with `restart_without_knowledge` it
    restarts on cp-bo's schedule, each tree drawing its picks afresh."""
    world = Attempts()
    base = method_config("quasi-random-restarts").search
    config = SearchConfig(**{**base.__dict__, "restart_unit": 5, "inconclusive_retries": 2})
    sampler = FirstChoices(keeps_knowledge=False)
    result = PWUCT(world, sampler, seed=3, config=config).run(40)
    assert sampler.fresh_roots == [1, 6, 11, 21, 26, 31]
    assert result.restarts == 5 and result.rollouts == result.rollouts_spent == 40
    firsts = [a for a in world.picks if a % 3 == 0]
    assert sorted(set(firsts)) == [3 * k for k in range(result.restarts + 1)]


def test_the_strongest_baseline_redraws_a_tree_closed_by_unproven_failures():
    config = method_config("quasi-random-restarts").search
    search = PWUCT(LuckyLater(), FirstChoices(keeps_knowledge=False), seed=1, config=config)
    strongest = search.run(200)
    paper = PWUCT(LuckyLater(), QuasiRandomSampler(), seed=1, config=SearchConfig()).run(200)
    assert strongest.solved and strongest.restarts == 1
    assert paper.exhausted and not paper.solved and paper.restarts == 0


def test_a_quasi_random_restarts_run_counts_rollouts_across_trees_and_records_the_switch():
    config = PlanConfig().with_overrides({"search.restart_unit": 1})
    result = run_plan(Unplaceable(), "quasi-random-restarts", 3, max_rollouts=10, config=config)
    assert not result.solved
    assert result.rollouts == result.rollouts_spent == 10  # summed over the 7 trees
    assert "tree restarted 6 times" in result.notes
    assert result.config["search"]["restart_without_knowledge"] is True
    plain = run_plan(Unplaceable(), "quasi-random", 3, max_rollouts=10, config=config)
    assert not any("restarted" in note for note in plain.notes)
    assert plain.config["search"]["restart_without_knowledge"] is False

"""The PW law, UCB, backup and reward on small hand-built trees and an analytic world."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from contract.models import CategoricalDomain, ContinuousDomain
from planner.config import SearchConfig
from planner.search import PWUCT
from planner.search.analytic import analytic_world, shelf_feasible
from planner.search.samplers.base import Proposal
from planner.search.samplers.quasi_random import QuasiRandomSampler
from planner.search.tree import (
    ChildNode,
    DecisionNode,
    backup,
    child_outlook,
    close,
    comparable_outlook,
    mark_hopeless,
    note_proposal,
    outlook,
    reward,
    ucb_select,
    widens,
)
from planner.skeleton import DecisionVar, OperatorCall
from planner.world import CheckResult, TransitionOutcome

CONFIG = SearchConfig()
PLAIN = replace(CONFIG, outlook_selection=False)  # plain UCB
W = CONFIG.outlook_prior_weight
CALL = OperatorCall("Inv-kin", ("body", "pose0", "#x"))
PASS = TransitionOutcome((CheckResult(CALL, True),))
FAIL = TransitionOutcome((CheckResult(CALL, False),))


CATEGORICAL_AB = DecisionVar(
    "#c", "#c", CategoricalDomain(choices=["a", "b"]), OperatorCall("Sample", (), ("#c",))
)


def node(domain=None) -> DecisionNode:
    domain = domain or ContinuousDomain(low=[0.0], high=[1.0])
    var = DecisionVar("#x", "#x", domain, OperatorCall("Sample", (), ("#x",)))
    return DecisionNode(0, var, {}, None)


def add_child(parent: DecisionNode, value, outcome=PASS, visits=1, r=0.0) -> ChildNode:
    child = ChildNode(value, parent, outcome, visits=visits, reward=r)
    parent.children.append(child)
    if outcome.ok:
        child.next = DecisionNode(1, parent.var, {}, None, child)
    else:
        close(child)
    return child


def test_pw_law_opens_a_child_when_visits_exceed_k_children_squared():
    n = node()
    n.visits = 1
    assert widens(n, CONFIG.pw_k)
    add_child(n, [0.1])
    n.visits = 13
    assert not widens(n, CONFIG.pw_k)
    n.visits = 14
    assert widens(n, CONFIG.pw_k)
    add_child(n, [0.2])
    n.visits = 54
    assert not widens(n, CONFIG.pw_k)
    n.visits = 55
    assert widens(n, CONFIG.pw_k)
    assert not widens(n, 20.0)


def test_pw_widens_at_once_when_every_child_is_a_dead_end():
    n = node()
    add_child(n, [0.1], FAIL)
    add_child(n, [0.2], FAIL)
    n.visits = 3
    assert widens(n, CONFIG.pw_k)
    assert ucb_select(n, PLAIN) is None


def test_a_hopeless_child_lets_its_parent_widen_but_stays_selectable():
    n = node()
    dead = add_child(n, [0.1], FAIL)
    trapped = add_child(n, [0.2])
    n.visits = 20  # below 13.5 * 2^2
    assert not widens(n, CONFIG.pw_k)
    mark_hopeless(trapped.next, True)
    assert widens(n, CONFIG.pw_k) and ucb_select(n, PLAIN) is trapped
    mark_hopeless(trapped.next, True)  # idempotent
    assert n.n_hopeless == 1
    mark_hopeless(trapped.next, False)
    assert not widens(n, CONFIG.pw_k) and n.n_hopeless == 0
    mark_hopeless(trapped.next, True)
    trapped.next.var = CATEGORICAL_AB
    add_child(trapped.next, "a", FAIL)
    add_child(trapped.next, "b", FAIL)  # the trapped subtree closes: counted once, as closed
    assert trapped.closed and n.n_hopeless == 0 and n.n_closed == 2 and dead.closed


def test_a_categorical_decision_stops_at_its_number_of_choices():
    n = node(CategoricalDomain(choices=["a", "b"]))
    add_child(n, "a", FAIL)
    add_child(n, "b", FAIL)
    n.visits = 1000
    assert not widens(n, CONFIG.pw_k)
    assert n.exhausted and n.closed and n.dead


def test_closing_propagates_up_through_exhausted_nodes():
    root = node(CategoricalDomain(choices=["a", "b"]))
    first = add_child(root, "a")
    add_child(root, "b", FAIL)
    assert first.next is not None and not root.closed
    inner = first.next
    inner.var = root.var  # categorical, two choices
    add_child(inner, "a", FAIL)
    assert not first.closed
    add_child(inner, "b", FAIL)
    assert first.closed and first.dead and root.closed and root.dead


def test_ucb_trades_reward_against_visits():
    n = node()
    well_known = add_child(n, [0.1], visits=10, r=0.05)
    fresh = add_child(n, [0.2], visits=1, r=0.0)
    n.visits = 11
    # 0.05 + 0.1 sqrt(ln 11 / 10) = 0.099 < 0 + 0.1 sqrt(ln 11) = 0.155
    assert ucb_select(n, PLAIN) is fresh
    fresh.visits = 10
    assert ucb_select(n, PLAIN) is well_known
    assert math.isclose(0.1 * math.sqrt(math.log(11) / 10), 0.04897, abs_tol=1e-4)


def test_ucb_skips_closed_children():
    n = node()
    add_child(n, [0.1], FAIL, visits=1, r=0.9)
    open_child = add_child(n, [0.2], visits=5, r=0.0)
    n.visits = 6
    assert ucb_select(n, PLAIN) is open_child


def test_backup_keeps_the_max_on_the_whole_path():
    root = node()
    first = add_child(root, [0.1])
    assert first.next is not None
    leaf = add_child(first.next, [0.5], FAIL)
    backup(leaf, 0.075)
    backup(leaf, 0.025)
    assert (leaf.reward, first.next.reward, first.reward, root.reward) == (0.075,) * 4


@pytest.mark.parametrize(
    ("passed", "total", "success", "expected"),
    [(1, 4, False, 0.025), (3, 4, False, 0.075), (4, 4, True, 1.1), (5, 8, False, 0.0625)],
)
def test_reward_is_a_tenth_of_the_depth_plus_one_on_success(passed, total, success, expected):
    assert reward(passed, total, success) == pytest.approx(expected)


def test_search_finds_a_feasible_binding_and_counts_rollouts():
    world = analytic_world("desk")
    result = PWUCT(world, QuasiRandomSampler(), seed=3).run(2000)
    assert result.solved and result.bindings is not None
    assert shelf_feasible(result.bindings["#pose12"])
    assert result.bindings["#dir1"] in ("front", "top")
    assert result.rollouts == result.rollouts_spent >= 1
    assert world.calls >= result.rollouts
    assert result.best_depth == 1.0


def test_search_is_reproducible_for_a_seed_and_varies_across_seeds():
    runs = [PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=s).run(500) for s in (1, 1, 2)]
    assert runs[0].bindings == runs[1].bindings and runs[0].rollouts == runs[1].rollouts
    assert runs[0].bindings != runs[2].bindings


def test_search_rewards_failures_by_depth():
    """0.1 d/D with d the layers passed, plus the passed share of the failed layer's checks."""
    world = analytic_world("desk")
    search = PWUCT(world, QuasiRandomSampler(), seed=0)
    search.run(5, stop_at_first=False)
    calls = len(world.skeleton.transitions[0].calls)
    failed = [c for c in search.root.children if not c.outcome.ok]
    assert failed
    for child in failed:
        passed = sum(check.ok for check in child.outcome.checks)
        assert passed < calls
        assert child.reward == pytest.approx(0.1 * (1 + passed / calls) / 4)
    for child in search.root.children:
        if child.outcome.ok and child.next is not None and child.next.children:
            assert child.success or child.reward >= 0.075


def test_budget_without_stopping_keeps_searching_after_the_first_solution():
    result = PWUCT(analytic_world("desk"), QuasiRandomSampler(), seed=3).run(
        300, stop_at_first=False
    )
    assert result.solved and result.rollouts_spent == 300
    assert result.rollouts < 300 and len(result.solutions) >= 1


class FadingSampler(QuasiRandomSampler):
    """Quasi-random values, each reported as less likely to be feasible than the one before."""

    def __init__(self) -> None:
        super().__init__()
        self.p = 0.5

    def propose(self, ctx):
        self.p *= 0.5
        return Proposal(super().propose(ctx), self.p)


def test_search_widens_above_nodes_whose_proposals_are_hopeless():
    def root_children(sampler) -> int:
        search = PWUCT(analytic_world("deskP"), sampler, seed=0)
        search.run(12, stop_at_first=False)
        return len(search.root.children)

    assert root_children(FadingSampler()) > root_children(QuasiRandomSampler())


def test_without_hopeless_widening_the_pw_law_alone_widens():
    def root_children(config: SearchConfig) -> int:
        search = PWUCT(analytic_world("deskP"), FadingSampler(), seed=0, config=config)
        search.run(12, stop_at_first=False)
        assert search.root.n_hopeless == 0 or config.hopeless_widening
        return len(search.root.children)

    plain = PWUCT(analytic_world("deskP"), QuasiRandomSampler(), seed=0)
    plain.run(12, stop_at_first=False)
    off = replace(CONFIG, hopeless_widening=False)
    assert root_children(off) == len(plain.root.children) < root_children(CONFIG)


def test_note_proposal_keeps_the_outlook_without_marking_hopeless_when_switched_off():
    n = node()
    for value in range(CONFIG.hopeless_min_children):
        add_child(n, [value / 10])
    off = replace(CONFIG, hopeless_widening=False)
    note_proposal(n, 0.5, off)
    note_proposal(n, 0.01, off)
    assert not n.hopeless and n.last_p_feasible == 0.01
    note_proposal(n, 0.01, CONFIG)
    assert n.hopeless


def test_selection_keeps_to_children_within_the_outlook_ratio_of_the_best():
    n = node(CategoricalDomain(choices=["a", "b", "c"]))
    trap = add_child(n, "a", visits=1, r=0.075)
    promising = add_child(n, "b", visits=9, r=0.075)
    n.visits = 10
    assert ucb_select(n, PLAIN) is trap  # plain UCB: the less visited
    assert outlook(n, W) is None  # not every open child rated: no outlook
    assert ucb_select(n, replace(CONFIG, outlook_ratio=1.5)) is trap
    note_proposal(trap.next, 0.02, CONFIG)
    note_proposal(promising.next, 0.3, CONFIG)
    assert outlook(n, W) == pytest.approx(W * 0.3 / (W + 9))
    assert ucb_select(n, replace(CONFIG, outlook_ratio=1.5)) is promising
    note_proposal(promising.next, 0.025, CONFIG)  # its own proposals have since failed
    assert ucb_select(n, replace(CONFIG, outlook_ratio=1.5)) is trap


def test_failures_through_a_choice_lower_its_outlook_but_not_a_placement_s():
    """A grasp whose placements keep failing is left for one the knowledge base rates lower
    but that has failed less; a placement child is a single value, its outlook the model's."""
    grasps = node(CategoricalDomain(choices=["top", "front", "right"]))
    trap = add_child(grasps, "top", visits=12, r=0.075)
    fresh = add_child(grasps, "front", visits=1, r=0.075)
    # An unseen grasp: the stated prior, far from its failures.
    note_proposal(trap.next, 0.5, CONFIG)
    note_proposal(fresh.next, 0.3, CONFIG)
    grasps.visits = 13
    assert child_outlook(trap, W) < child_outlook(fresh, W) < 0.3
    assert ucb_select(grasps, CONFIG) is fresh
    placements = node(ContinuousDomain(low=[0.0], high=[1.0]))
    tried = add_child(placements, [0.5], visits=12, r=0.075)
    note_proposal(tried.next, 0.5, CONFIG)
    assert child_outlook(tried, W) == 0.5


def test_an_outlook_is_comparable_while_values_are_left_and_children_are_rated():
    n = node(CategoricalDomain(choices=["a", "b"]))
    child = add_child(n, "a")
    assert comparable_outlook(n, W) is None  # its child is not rated yet
    note_proposal(child.next, 0.1, CONFIG)
    assert comparable_outlook(n, W) == pytest.approx(W * 0.1 / (W + child.visits))
    add_child(n, "b", FAIL)
    assert comparable_outlook(n, W) is None  # exhausted


class OutlookSampler(QuasiRandomSampler):
    """Rates proposals under `#dir1 = top` as ever less likely and any untried grasp as 0.4: a
    knowledge base that has learned that no placement follows `top`."""

    def __init__(self) -> None:
        super().__init__()
        self.untried_asked = 0

    def propose(self, ctx):
        value = super().propose(ctx)
        if ctx.depth == 1:
            p = 0.4 if ctx.path["#dir1"] != "top" else 0.4 / (1 + len(ctx.siblings))
            return Proposal(value, p)
        return "top" if "top" not in ctx.siblings else value

    def propose_untried(self, ctx):
        self.untried_asked += 1
        return Proposal(super().propose(ctx), 0.4)


def test_search_leaves_a_choice_whose_outlook_fell_for_an_untried_one():
    def top_visits(sampler, ratio: float) -> int:
        config = replace(CONFIG, outlook_ratio=ratio)
        search = PWUCT(analytic_world("deskP"), sampler, seed=0, config=config)
        search.run(40, stop_at_first=False)
        top = next(c for c in search.root.children if c.value == "top")
        return top.visits

    guided = OutlookSampler()
    assert top_visits(guided, 1.5) < 10 < top_visits(OutlookSampler(), math.inf)
    assert guided.untried_asked > 0


def test_the_tree_switches_off_leave_plain_pw_uct():
    """With the outlook and hopeless rules off (the paper's tree), a sampler's ratings change
    nothing: the search takes the same course as with the same values unrated."""

    class Unrated(OutlookSampler):
        def propose(self, ctx):
            proposal = super().propose(ctx)
            return proposal.value if isinstance(proposal, Proposal) else proposal

    def course(sampler, config: SearchConfig) -> list[tuple[object, int]]:
        search = PWUCT(analytic_world("deskP"), sampler, seed=0, config=config)
        search.run(40, stop_at_first=False)
        return [(c.value, c.visits) for c in search.root.children]

    paper = replace(
        CONFIG, outlook_widening=False, outlook_selection=False, hopeless_widening=False
    )
    rated = OutlookSampler()
    assert course(rated, paper) == course(Unrated(), paper)
    assert rated.untried_asked == 0
    assert course(OutlookSampler(), CONFIG) != course(rated, paper)


def test_selection_ignores_outlooks_when_switched_off():
    n = node(CategoricalDomain(choices=["a", "b", "c"]))
    low = add_child(n, "a", visits=1, r=0.075)
    high = add_child(n, "b", visits=9, r=0.075)
    note_proposal(low.next, 0.01, CONFIG)
    note_proposal(high.next, 0.5, CONFIG)
    n.visits = 10
    assert ucb_select(n, CONFIG) is high
    assert ucb_select(n, PLAIN) is low


def test_every_few_visits_selection_ignores_the_outlook():
    every = CONFIG.outlook_free_every
    n = node(CategoricalDomain(choices=["a", "b", "c"]))
    low = add_child(n, "a", visits=1, r=0.075)
    high = add_child(n, "b", visits=9, r=0.075)
    note_proposal(low.next, 0.01, CONFIG)
    note_proposal(high.next, 0.5, CONFIG)
    picks = []
    for visits in range(1, 3 * every + 1):
        n.visits = visits
        picks.append(ucb_select(n, CONFIG))
    assert picks.count(low) == 3 and picks.count(high) == 3 * every - 3

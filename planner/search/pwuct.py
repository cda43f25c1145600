"""PW-UCT binding search (Algorithm 1 of the paper) over any `BindingWorld`.

Each rollout descends from the root: at a decision node it adds a visit, then either opens a
new child (the sampler proposes a value and the world runs the following transition layer) or
selects an open child by UCB. A rollout ends at a failed transition (reward `0.1 d/D`, where d
counts the layers passed and the passed share of the failed layer's checks) or at a
full binding list that passed every transition (reward `1.1`); the reward is backed up by max.
Beside it, each child keeps a *score*: the reward with the failed check's own progress added (the
world's detail `progress`, e.g. how close IK came), backed up by max the same way. UCB ignores
it; samplers see it as `SampleContext.sibling_scores` (MCTS-BO regresses on it).
With a sampler that rates its proposals (`Proposal`), a node also opens an untried value that is
rated well above its children's outlook, and UCB keeps to the children with the best outlook
(`SearchConfig.outlook_ratio`; each rule has its switch).
With `SearchConfig.restart_unit` and a sampler whose knowledge outlives the tree (any sampler
with `SearchConfig.restart_without_knowledge`), the tree is dropped and grown anew on Luby's
(or a doubling) schedule; rollouts count across trees (with `SearchConfig.restart_redraws`
each tree draws the world's randomised checks afresh).
A sampler may hand out a whole binding to follow (`Sampler.chain`, such as one another
planner passed): that rollout takes its values, opening the children the tree lacks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import attrgetter
from typing import Protocol

import numpy as np

from contract.models import Value
from planner.config import SearchConfig
from planner.search.samplers.base import Proposal, SampleContext, Sampler
from planner.search.tree import (
    ChildNode,
    DecisionNode,
    add_child,
    backup,
    backup_score,
    check_alternating,
    close,
    comparable_outlook,
    note_proposal,
    reward,
    ucb_select,
    widens,
)
from planner.world import PROGRESS_CAP, BindingWorld, TransitionOutcome

_REWARD = attrgetter("reward")
_SCORE = attrgetter("score")
_VISITS = attrgetter("visits")


class SearchObserver(Protocol):
    """Sees every transition the search runs (the knowledge base labels points from them)."""

    def on_transition(
        self, index: int, bindings: dict[str, Value], outcome: TransitionOutcome, rollout: int
    ) -> None: ...

    def on_rollout_end(self, rollout: int) -> None: ...


@dataclass(frozen=True)
class SearchProgress:
    rollouts: int
    best_depth: float
    solved: bool


@dataclass
class SearchResult:
    solved: bool
    rollouts: int
    rollouts_spent: int
    bindings: dict[str, Value] | None
    best_depth: float
    sim_s: float
    sample_s: float
    exhausted: bool = False
    timed_out: bool = False  # stopped by the deadline, not by the rollout budget
    restarts: int = 0
    solutions: list[dict[str, Value]] = field(default_factory=list)


def luby(i: int) -> int:
    """The i-th term (from 1) of Luby, Sinclair and Zuckerman's universal restart sequence:
    1, 1, 2, 1, 1, 2, 4, 1, 1, 2, 1, 1, 2, 4, 8, ..."""
    if i < 1:
        raise ValueError(f"Luby's sequence starts at 1, not {i}")
    while True:
        k = i.bit_length()
        if i == (1 << k) - 1:
            return 1 << (k - 1)
        i -= (1 << (k - 1)) - 1


class PWUCT:
    def __init__(
        self,
        world: BindingWorld,
        sampler: Sampler,
        *,
        seed: int,
        config: SearchConfig | None = None,
        observer: SearchObserver | None = None,
    ) -> None:
        check_alternating(world.skeleton)
        self.config = config if config is not None else SearchConfig()
        self.world = world
        self.sampler = sampler
        self.observer = observer
        self.rng = np.random.default_rng(seed)
        self.decisions = world.skeleton.decisions
        self.n_layers = len(world.skeleton.layers)
        self.root = self._new_root()
        # Only a sampler whose knowledge outlives the tree restarts (`Sampler.keeps_knowledge`),
        # unless every sampler is to (`SearchConfig.restart_without_knowledge`).
        restarts = sampler.keeps_knowledge or self.config.restart_without_knowledge
        self._restart_unit = self.config.restart_unit if restarts else 0
        self.restarts = 0
        self._tree_rollouts = 0
        self._unproven = False  # whether this tree met a failure another draw may undo
        self.rollout = 0
        self.best_depth = 0.0
        self.sim_s = 0.0
        self.sample_s = 0.0

    def run(
        self,
        max_rollouts: int = 2000,
        *,
        stop_at_first: bool = True,
        progress: Callable[[SearchProgress], None] | None = None,
        deadline: float | None = None,
    ) -> SearchResult:
        """Rollouts until the first feasible binding list (or the whole budget). `deadline`, a
        `time.perf_counter()` value: no rollout starts after it (one under way finishes)."""
        first: int | None = None
        solutions: list[dict[str, Value]] = []
        timed_out = False
        while self.rollout < max_rollouts:
            if deadline is not None and time.perf_counter() >= deadline:
                timed_out = True
                break
            if self.root.closed and not self._redraw_closed_tree():
                break
            found = self._rollout()
            if found is None:
                continue
            self.rollout += 1
            if self.observer is not None:
                self.observer.on_rollout_end(self.rollout)
            if found:
                solutions.append(found)
                first = first or self.rollout
            if progress is not None:
                progress(SearchProgress(self.rollout, self.best_depth, first is not None))
            if first is not None and stop_at_first:
                break
            self._tree_rollouts += 1
            if (
                self._restart_unit
                and self._tree_rollouts >= self._restart_unit * self._tree_units()
                and self.rollout < max_rollouts
            ):
                self._restart()
        return SearchResult(
            solved=first is not None,
            rollouts=first if first is not None else self.rollout,
            rollouts_spent=self.rollout,
            bindings=solutions[0] if solutions else None,
            best_depth=self.best_depth,
            sim_s=self.sim_s,
            sample_s=self.sample_s,
            exhausted=self.root.closed,
            timed_out=timed_out,
            restarts=self.restarts,
            solutions=solutions,
        )

    def _restart(self) -> None:
        self.root = self._new_root()
        self.restarts += 1
        self._tree_rollouts = 0
        self._unproven = False

    def _redraw_closed_tree(self) -> bool:
        """With `SearchConfig.restart_redraws`, a tree that closed on a failure no draw proved
        (an IK or motion search that found nothing) is grown anew, drawing afresh, instead of
        ending the search; a tree closed by proofs alone ends it."""
        if not (self._restart_unit and self.config.restart_redraws and self._unproven):
            return False
        self._restart()
        return True

    def _tree_units(self) -> int:
        """The current tree's allowance, in `restart_unit`s."""
        if self.config.restart_schedule == "geometric":
            return 1 << self.restarts
        return luby(self.restarts + 1)

    def _new_root(self) -> DecisionNode:
        return DecisionNode(
            0, self.decisions[0], {}, self.world.initial_state(), retries=self._retries(0, None)
        )

    def _rollout(self) -> dict[str, Value] | None:
        """One descent; the bindings on success, {} on failure, None if it met only closed
        nodes (a categorical subtree turned out exhausted: nothing was run, no rollout spent)."""
        started = time.perf_counter()
        chain = self.sampler.chain() or {}
        self.sample_s += time.perf_counter() - started
        node = self.root
        while True:
            node.visits += 1
            if (followed := chain.get(node.var.var)) is not None:
                child = self._follow(node, followed)
            elif widens(node, self.config.pw_k):
                child = self._expand(node)
            elif (untried := self._better_untried(node)) is not None:
                child = self._expand(node, untried)
            else:
                selected = ucb_select(node, self.config)
                if selected is None:
                    return None
                child = selected
            child.visits += 1
            if child.closed:
                return self._finish(child)
            assert child.next is not None
            node = child.next

    def _follow(self, node: DecisionNode, value: Value) -> ChildNode:
        """The child of `value`, opened if the node lacks it (a chain the sampler hands out)."""
        for child in node.children:
            if child.value == value:
                return child
        return self._expand(node, forced=value)

    def _finish(self, child: ChildNode) -> dict[str, Value]:
        node = child.parent
        layers_passed = self.n_layers if child.success else self._depth_reached(child)
        r = reward(layers_passed, self.n_layers, child.success)
        self.best_depth = max(self.best_depth, layers_passed / self.n_layers)
        backup(child, r)
        graded = self._graded_depth(child) if not child.success else None
        backup_score(child, r if graded is None else reward(graded, self.n_layers, False))
        return {**node.path, node.var.var: child.value} if child.success else {}

    def _depth_reached(self, child: ChildNode) -> float:
        """Layers passed by a failed rollout: those before its transition layer, plus the share
        of that layer's checks that passed. A placement that passed IK and failed in motion
        planning got further than one IK refused; with whole layers only, every failed child of
        a node would score alike and MCTS-BO's GP would see no signal."""
        index = child.parent.index
        calls = len(self.world.skeleton.transitions[index].calls)
        passed = sum(check.ok for check in child.outcome.checks)
        return 2 * index + 1 + passed / max(calls, 1)

    def _graded_depth(self, child: ChildNode) -> float:
        """`_depth_reached` plus the failed check's own progress, its detail `progress` in
        [0, 1) (the world's measure of how close it came: an IK residual, a penetration), as a
        share of one check: within the band of the failed check, so it never ranks a child
        above one that got further. MCTS-BO's target only; the tree's reward ignores it."""
        failed = child.outcome.failed
        progress = failed.detail.get("progress", 0.0) if failed is not None else 0.0
        progress = min(max(float(progress), 0.0), PROGRESS_CAP)
        calls = len(self.world.skeleton.transitions[child.parent.index].calls)
        return self._depth_reached(child) + progress / max(calls, 1)

    def _context(self, node: DecisionNode) -> SampleContext:
        return SampleContext(
            var=node.var,
            path=dict(node.path),
            siblings=tuple(node.values),
            sibling_rewards=tuple(map(_REWARD, node.children)),
            sibling_visits=tuple(map(_VISITS, node.children)),
            depth=node.index,
            rollout=self.rollout + 1,
            rng=self.rng,
            sibling_matrix=node.value_matrix,
            sibling_scores=tuple(map(_SCORE, node.children)),
        )

    def _better_untried(self, node: DecisionNode) -> Proposal | None:
        """The sampler's best untried value, if the knowledge base rates it `outlook_ratio`
        times above every open child's outlook (see `SearchConfig.outlook_widening`)."""
        if not self.config.outlook_widening:
            return None
        best = comparable_outlook(node, self.config.outlook_prior_weight)
        if best is None:
            return None
        started = time.perf_counter()
        proposal = self.sampler.propose_untried(self._context(node))
        self.sample_s += time.perf_counter() - started
        if proposal is None or proposal.p_feasible <= self.config.outlook_ratio * best:
            return None
        return proposal

    def _draw(self, attempt: int) -> int:
        """The world's attempt number of a transition: the choice's own attempt, and with
        `SearchConfig.restart_redraws` the tree's restart count, so that each tree draws anew."""
        if not self.config.restart_redraws:
            return attempt
        return attempt + self.restarts * (self.config.inconclusive_retries + 1)

    def _retries(self, index: int, parent: DecisionNode | None) -> int:
        """Further attempts at a choice of decision `index` that failed inconclusively: only
        where every decision from the root to it is categorical (see `planner.search.tree`)."""
        if self.decisions[index].domain.kind != "categorical":
            return 0
        if parent is not None and not parent.retries:  # a continuous parent has none
            return 0
        return self.config.inconclusive_retries

    def _expand(
        self, node: DecisionNode, chosen: Proposal | None = None, forced: Value | None = None
    ) -> ChildNode:
        attempt = 0
        if forced is not None:
            value = forced
        elif chosen is None and node.all_tried:
            retry = node.retry_choice()
            assert retry is not None, "widens() opens an all-tried node only to retry a choice"
            value, attempt = retry
        else:
            ctx = self._context(node)
            started = time.perf_counter()
            proposal = chosen if chosen is not None else self.sampler.propose(ctx)
            self.sample_s += time.perf_counter() - started
            if isinstance(proposal, Proposal):
                value = proposal.value
                note_proposal(node, proposal.p_feasible, self.config)
            else:
                value = proposal
            if node.n_choices is not None and value in ctx.siblings:
                raise RuntimeError(f"sampler {self.sampler.name} proposed a tried choice {value!r}")
        bindings = {**node.path, node.var.var: value}
        started = time.perf_counter()
        outcome = self.world.transition(
            node.index, bindings, node.state, attempt=self._draw(attempt)
        )
        self.sim_s += time.perf_counter() - started
        self._unproven = self._unproven or not outcome.conclusive
        if self.observer is not None:
            self.observer.on_transition(node.index, bindings, outcome, self.rollout + 1)
        child = ChildNode(value, node, outcome)
        add_child(node, child)
        if outcome.ok and node.index + 1 < len(self.decisions):
            child.next = DecisionNode(
                node.index + 1,
                self.decisions[node.index + 1],
                bindings,
                outcome.state,
                child,
                retries=self._retries(node.index + 1, node),
            )
        else:
            child.success = outcome.ok
            close(child)
        return child

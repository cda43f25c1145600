"""The PW-UCT decision tree: nodes, the progressive-widening law, UCB selection, backup.

A `DecisionNode` binds one decision variable of the skeleton; each of its children is a
`ChildNode`: a chosen value plus the outcome of the transition layer that follows it. A child
whose transition passed owns the next decision node (or is a success at the last layer); a child
whose transition failed is a dead end. Children that are dead ends or successes are *closed*:
UCB never selects them again, and a node whose children are all closed widens at once.

A categorical choice whose transition failed *inconclusively* (IK restarts or a sampling motion
planner found nothing) is not proven infeasible. Where no continuous decision lies above it
(`DecisionNode.retries` > 0), a node that has tried every choice may try such a choice again,
with fresh random draws, instead of closing: a seed's unlucky first IK at the start must not
doom the run. Below a continuous decision a new value of that decision draws afresh anyway.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from contract.models import CategoricalDomain, Value
from planner.config import SearchConfig
from planner.skeleton import DecisionVar, Skeleton
from planner.world import TransitionOutcome


@dataclass(eq=False)
class ChildNode:
    value: Value
    parent: DecisionNode
    outcome: TransitionOutcome
    visits: int = 0
    reward: float = 0.0
    score: float = 0.0  # `reward` with a failed check's progress; MCTS-BO's target, not UCB's
    next: DecisionNode | None = None
    success: bool = False
    closed: bool = False  # set by `close`: a dead end, a success, or a subtree with nothing left

    @property
    def dead(self) -> bool:
        """A failed transition, or a subtree with nothing left to try and no success in it."""
        return not self.outcome.ok or (self.next is not None and self.next.dead)


@dataclass(eq=False)
class DecisionNode:
    index: int
    var: DecisionVar
    path: dict[str, Value]
    state: object
    parent: ChildNode | None = None
    children: list[ChildNode] = field(default_factory=list)
    visits: int = 0
    reward: float = 0.0
    n_closed: int = 0
    n_hopeless: int = 0  # open children whose next node is hopeless
    retries: int = 0  # further attempts a choice that failed inconclusively may get
    hopeless: bool = False  # counted in the parent's widening (see `mark_hopeless`)
    first_p_feasible: float | None = None  # the knowledge base's view when the search came here
    last_p_feasible: float | None = None  # its view at the latest proposal: the outlook
    values: list[Value] = field(default_factory=list)  # the children's values, in order
    _matrix: np.ndarray | None = field(default=None, repr=False)
    _filled: int = field(default=0, repr=False)

    @property
    def value_matrix(self) -> np.ndarray | None:
        """The continuous children's values as an `(n, dim)` array (a view); None if categorical."""
        if self.n_choices is not None:
            return None
        n = len(self.values)
        if self._matrix is None or self._matrix.shape[0] < n:
            capacity = max(16, 2 * n)
            matrix = np.empty((capacity, len(self.var.domain.low)))  # type: ignore[union-attr]
            if n:
                matrix[:n] = np.asarray(self.values, dtype=float)
            self._matrix, self._filled = matrix, n
        elif self._filled < n:
            self._matrix[self._filled : n] = np.asarray(self.values[self._filled :], dtype=float)
            self._filled = n
        return self._matrix[:n]

    @property
    def n_choices(self) -> int | None:
        domain = self.var.domain
        return len(domain.choices) if isinstance(domain, CategoricalDomain) else None

    @property
    def all_tried(self) -> bool:
        """A categorical decision with every choice tried at least once."""
        limit = self.n_choices
        return limit is not None and len({c.value for c in self.children}) >= limit

    @property
    def exhausted(self) -> bool:
        """Every choice tried and none left to retry; a continuous decision never is."""
        return self.all_tried and self.retry_choice() is None

    def retry_choice(self) -> tuple[Value, int] | None:
        """The choice to attempt again and its attempt number: among the choices whose every
        attempt failed inconclusively, with attempts left, the least attempted (the earliest
        on a tie); None if there is none."""
        if not self.retries:
            return None
        attempts: dict[Value, int] = {}
        for child in self.children:
            value = child.value
            if child.outcome.ok or child.outcome.conclusive:
                attempts[value] = self.retries + 1  # passed, or proven infeasible: not retried
            else:
                attempts[value] = attempts.get(value, 0) + 1
        left = [(n, value) for value, n in attempts.items() if n <= self.retries]
        if not left:
            return None
        n, value = min(left, key=lambda pair: pair[0])
        return value, n

    @property
    def closed(self) -> bool:
        """Exhausted, and every child closed: nothing left to try below this node."""
        return self.exhausted and self.n_closed == len(self.children)

    @property
    def dead(self) -> bool:
        """Closed without any success below."""
        return self.exhausted and all(c.dead for c in self.children)


def add_child(node: DecisionNode, child: ChildNode) -> None:
    node.children.append(child)
    node.values.append(child.value)


def mark_hopeless(node: DecisionNode, hopeless: bool) -> None:
    """Record whether `node` is hopeless, in the count its parent widens by."""
    if node.hopeless == hopeless:
        return
    node.hopeless = hopeless
    if node.parent is not None and not node.parent.closed:
        node.parent.parent.n_hopeless += 1 if hopeless else -1


def note_proposal(node: DecisionNode, p_feasible: float, config: SearchConfig) -> None:
    """Keep the knowledge base's P(feasible) of `node`'s latest proposal (its outlook) and update
    its hopeless flag from it, measured against the first one made at this node."""
    if node.first_p_feasible is None:
        node.first_p_feasible = p_feasible
    node.last_p_feasible = p_feasible
    if not config.hopeless_widening:
        return
    tried = len(node.children) >= config.hopeless_min_children
    mark_hopeless(node, tried and p_feasible < config.hopeless_ratio * node.first_p_feasible)


def close(child: ChildNode) -> None:
    """Mark `child` closed and propagate: a node whose last open child closes, with no choice
    left, closes the child that leads to it, and so on up."""
    current: ChildNode | None = child
    while current is not None and not current.closed:
        if current.next is not None and current.next.hopeless:
            current.parent.n_hopeless -= 1  # counted once, as closed
        current.closed = True
        parent = current.parent
        parent.n_closed += 1
        current = parent.parent if parent.closed else None


def widens(node: DecisionNode, k: float) -> bool:
    """The PW law: a new child when N > k |C|^2, or when every child is closed or hopeless;
    never beyond a categorical decision's choices and their retries."""
    n_children = len(node.children)
    if node.exhausted:
        return False
    if node.n_closed + node.n_hopeless >= n_children:
        return True
    return node.visits > k * n_children**2


def child_outlook(child: ChildNode, prior_weight: float) -> float | None:
    """The knowledge base's view below `child` after the failures through it (see
    `SearchConfig.outlook_prior_weight`); None if it has not rated the node below. The child
    of a continuous decision keeps the model's view."""
    below = child.next
    if below is None:
        return None
    p = below.last_p_feasible
    if p is None or child.parent.n_choices is None:
        return p
    failures = 0 if child.success else child.visits
    return prior_weight * p / (prior_weight + failures)


def outlook(node: DecisionNode, prior_weight: float) -> float | None:
    """The best outlook among `node`'s open children; None unless every open child (one at
    least) has been rated by the knowledge base."""
    best: float | None = None
    for child in node.children:
        if child.closed:
            continue
        p = child_outlook(child, prior_weight)
        if p is None:
            return None
        best = p if best is None else max(best, p)
    return best


def comparable_outlook(node: DecisionNode, prior_weight: float) -> float | None:
    """The outlook an untried value of `node` is compared with: None unless untried values are
    left and every open child is rated."""
    if node.all_tried:
        return None
    return outlook(node, prior_weight)


def ucb_select(node: DecisionNode, config: SearchConfig) -> ChildNode | None:
    """The open child maximising `reward + c sqrt(ln N / n)`; None when all are closed.
    With `outlook_selection`, a node whose open children are all rated selects only among those
    within `outlook_ratio` of the best outlook, except at every `outlook_free_every`-th visit: a
    subtree whose outlook stays high while it keeps failing (a failure the knowledge base does
    not model, or a model that does not learn it) must not keep the others from being reached.
    Ties go to the earliest child, so selection is deterministic."""
    best: ChildNode | None = None
    best_score = -math.inf
    log_n = math.log(max(node.visits, 1))
    weight, ratio = config.outlook_prior_weight, config.outlook_ratio
    guided = config.outlook_selection and node.visits % config.outlook_free_every != 0
    best_outlook = outlook(node, weight) if guided else None
    for child in node.children:
        if child.closed:
            continue
        if best_outlook is not None:
            rated = child_outlook(child, weight)
            assert rated is not None
            if rated * ratio < best_outlook:
                continue
        score = child.reward + config.ucb_c * math.sqrt(log_n / max(child.visits, 1))
        if score > best_score:
            best, best_score = child, score
    return best


def backup(child: ChildNode, reward: float) -> None:
    """Backup by max: every node on the path keeps the best reward seen below it."""
    node: ChildNode | None = child
    while node is not None:
        node.reward = max(node.reward, reward)
        parent = node.parent
        parent.reward = max(parent.reward, reward)
        node = parent.parent


def backup_score(child: ChildNode, score: float) -> None:
    """Backup by max of the graded score (`ChildNode.score`), beside `backup` of the reward."""
    node: ChildNode | None = child
    while node is not None:
        node.score = max(node.score, score)
        node = node.parent.parent


def reward(layers_passed: float, layers_total: int, success: bool) -> float:
    """The paper's reward `0.1 d_end / d_total + r_end`; `d_end` counts skeleton layers passed
    (with the passed share of a failed transition layer's checks)."""
    return 0.1 * layers_passed / layers_total + (1.0 if success else 0.0)


def check_alternating(skeleton: Skeleton) -> None:
    """The tree needs decision, transition, decision, transition, ... (Table I)."""
    kinds = [layer.kind for layer in skeleton.layers]
    expected = ["decision", "transition"] * (len(kinds) // 2)
    if not kinds or kinds != expected:
        raise ValueError(f"skeleton layers must alternate decision/transition, got {kinds}")
    if any(layer.decision is None for layer in skeleton.layers if layer.kind == "decision"):
        raise ValueError("every decision layer needs its DecisionVar")

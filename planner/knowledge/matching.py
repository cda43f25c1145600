"""Type matching and activation: which known types bind which checks of this task.

A failed check becomes a causal graph; the first time a graph is met in this run, `types/match`
tells its type ID (prematch has usually told it already), and the type becomes *active* at that
check with its labels bound to this task's variables (if the type existed before, this is
transfer: its points count as activated). Every later evaluation of an active type's check adds
a labelled point: feasible when the check passes, infeasible when it fails the same way. Before
any failure, prematch asks `types/match` about every graph this task could produce (each check x
each culprit the world may report), so types that earlier tasks learned guide the very first
expansions.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

from client.errors import BadRequest
from contract.models import Constraint, Graph, MatchResult, Value
from planner.failures import Encodings, FailureGraph, failure_graph
from planner.knowledge.client import KnowledgeClient
from planner.knowledge.stats import KnowledgeStats
from planner.skeleton import Skeleton
from planner.world import CheckResult, TransitionOutcome

Key = tuple[int, int, str | None]  # (transition index, call index, culprit body)
Observed = tuple[Key, FailureGraph, dict[str, Value], bool]  # a point of this rollout
StoredWith = Callable[[str, FailureGraph], int]


@dataclass(frozen=True)
class Activation:
    """A type bound to one check of this task, through its decision labels."""

    type_id: str
    failure: FailureGraph
    transferred: bool
    n_points: int
    stored_with: int = 0  # a new type exists in the service once this batch has been posted

    @property
    def vars(self) -> frozenset[str]:
        return frozenset(self.failure.bind.values())


@lru_cache(maxsize=16)
def _task_graphs(skeleton: str, encodings: Encodings) -> dict[Key, FailureGraph]:
    """The failure graphs of one skeleton (by its repr) and its encodings, shared by the
    sessions of a process. A graph depends only on these, the check and the culprit, and a
    planner process (a bench worker, a planner loop) plans one task many times, and building
    every graph prematch looks up costs a share of a short run."""
    return {}


class TypeMatcher:
    """The graphs of one run, the types they matched and where each type is active.

    `stored_with(type_id, graph)` tells, for a type this run creates, the poster batch after
    which the service holds it (0: no need to wait)."""

    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        skeleton: Skeleton,
        encodings: Encodings,
        stats: KnowledgeStats,
        stored_with: StoredWith,
        *,
        match_chunk: int,
    ) -> None:
        self._client, self._kb, self._skeleton = client, kb, skeleton
        self._encodings = encodings
        self._stats = stats
        self._stored_with = stored_with
        self._match_chunk = match_chunk
        self._graphs = _task_graphs(repr(skeleton), encodings)
        self.active: dict[Key, Activation] = {}
        self._by_check: dict[tuple[int, int], list[tuple[Key, Activation]]] = {}
        self._unmatched: dict[Key, FailureGraph] = {}
        self._absent: dict[Key, str] = {}  # graphs prematch found absent: their type IDs
        self.types: set[str] = set()

    def prematch(self, culprits: tuple[str, ...]) -> int:
        """Activate the known types among every graph this task could produce with these
        culprits; how many were found."""
        for t, layer in enumerate(self._skeleton.transitions):
            for call in layer.calls:
                for culprit in (None, *culprits):
                    key = (t, layer.calls.index(call), culprit)
                    fg = self._graph(key, t, CheckResult(call, False), culprit)
                    if fg.bind:
                        self._unmatched[key] = fg
        return self.match(only_existing=True)

    def observe(
        self, index: int, values: dict[str, Value], outcome: TransitionOutcome
    ) -> list[Observed]:
        """The points a transition gives: each check of an active type that passed, and each
        failed check (its graph queued for matching if new)."""
        observed: list[Observed] = []
        for position, check in enumerate(outcome.checks):
            if check.ok:
                for key, activation in self._by_check.get((index, position), ()):
                    x = activation.failure.x(values)
                    observed.append((key, activation.failure, x, True))
                continue
            culprit = check.culprits[0].body if check.culprits else None
            key = (index, position, culprit)
            fg = self._graph(key, index, check, culprit)
            if not fg.bind:
                continue
            observed.append((key, fg, fg.x(values), False))
            if key not in self.active:
                self._unmatched[key] = fg
        return observed

    def match(self, *, only_existing: bool) -> int:
        """Ask the dictionary about the graphs met (or imagined) but not matched yet. A graph
        that prematch found absent becomes a new type without asking again: prematch told its
        type ID, and the round trip (a fifth of a guided regrasp run's knowledge-base time on a
        busy machine) would only say whether another planner created it in the meantime."""
        if not only_existing:
            for key in [k for k in self._unmatched if k in self._absent]:
                absent = MatchResult(type_id=self._absent.pop(key), exists=False, n_points=0)
                self._activate(key, self._unmatched.pop(key), absent)
        if not self._unmatched:
            return 0
        keys = list(self._unmatched)
        graphs = [self._unmatched[k].graph for k in keys]
        started = time.perf_counter()
        try:
            results: list[MatchResult | None] = []
            chunk = self._match_chunk
            for start in range(0, len(graphs), chunk):
                results.extend(self._client.match_types(self._kb, graphs[start : start + chunk]))
        except BadRequest:
            results = [self._match_one(graph) for graph in graphs]
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self._stats.event(f"match failed: {exc}")
            return 0
        finally:
            self._stats.spent("match", time.perf_counter() - started)
        activated = 0
        for key, result in zip(keys, results, strict=True):
            fg = self._unmatched.pop(key)
            if result is None:
                continue
            if only_existing and not result.exists:
                self._absent[key] = result.type_id
                continue
            self._activate(key, fg, result)
            activated += int(result.exists)
        return activated

    def watched(self) -> list[str]:
        """The active types, then the types of graphs prematch found absent (another planner
        may create them)."""
        absent = set(self._absent.values()) - self.types
        return [*sorted(self.types), *sorted(absent)]

    def born(self, created: dict[str, int]) -> int:
        """Activate the absent types another planner created (type ID -> its points so far);
        how many of them were new to this run."""
        new = 0
        for key, type_id in [(k, t) for k, t in self._absent.items() if t in created]:
            del self._absent[key]
            if type_id not in self.types:
                new += 1
            result = MatchResult(type_id=type_id, exists=True, n_points=created[type_id])
            self._activate(key, self._graphs[key], result)
        return new

    def constraints_at(
        self,
        var: str,
        path: dict[str, Value],
        *,
        lookahead: bool,
        ready: Callable[[Activation], None],
    ) -> list[Constraint]:
        """The active types that constrain this decision: those whose decision vertexes include
        it, with earlier ones (fixed on this path); with `lookahead`, also later ones (optimised
        jointly, so that this decision leaves a feasible continuation: a grasp that no placement
        can follow is avoided at the grasp), and then every type on those later decisions, so
        that the continuation is feasible as a whole (pack's first box leaves room for the second
        and the third side by side, not for each of them on the same spot). `ready` is called
        with each before it is used (to wait until the service holds it)."""
        known = {*path, var}
        chosen = [a for a in self.active.values() if var in a.vars]
        if lookahead:
            reached = {v for a in chosen for v in a.vars} | known
            ahead = reached - known
            rest = [a for a in self.active.values() if var not in a.vars]
            while ahead:
                joined = [a for a in rest if a.vars & ahead]
                rest = [a for a in rest if not a.vars & ahead]
                chosen += joined
                ahead = {v for a in joined for v in a.vars} - reached
                reached |= ahead
        else:
            chosen = [a for a in chosen if a.vars <= known]
        seen: set[tuple[str, tuple[tuple[str, str], ...]]] = set()
        constraints: list[Constraint] = []
        for activation in chosen:
            ready(activation)
            bind = tuple(sorted(activation.failure.bind.items()))
            if (activation.type_id, bind) in seen:
                continue
            seen.add((activation.type_id, bind))
            constraints.append(Constraint(type_id=activation.type_id, bind=dict(bind)))
        return constraints

    def _graph(self, key: Key, t: int, check: CheckResult, culprit: str | None) -> FailureGraph:
        if key not in self._graphs:
            self._graphs[key] = failure_graph(self._skeleton, t, check, culprit, self._encodings)
        return self._graphs[key]

    def _match_one(self, graph: Graph) -> MatchResult | None:
        """One graph alone, so that a graph the service rejects does not block the others."""
        try:
            return self._client.match_types(self._kb, [graph])[0]
        except BadRequest as exc:
            self._stats.event(f"graph rejected: {exc}")
            return None

    def _activate(self, key: Key, fg: FailureGraph, result: MatchResult) -> None:
        transferred = result.exists and result.n_points > 0
        stored_with = 0 if result.exists else self._stored_with(result.type_id, fg)
        activation = Activation(result.type_id, fg, transferred, result.n_points, stored_with)
        self.active[key] = activation
        self._by_check.setdefault(fg.check, []).append((key, activation))
        if result.type_id in self.types:
            return  # the same type at one more check: counted once
        self.types.add(result.type_id)
        self._stats.types_active += 1
        if transferred:
            self._stats.types_activated += 1
            self._stats.points_activated += result.n_points

"""The knowledge base in the loop of one binding search.

The session observes every transition the search runs. A failed check becomes a causal graph and an
infeasible point; the first time a graph is met in this run, `types/match` tells its type ID
(prematch has usually told it already), and the type becomes *active* at that check with its labels
bound to this task's variables (if the type existed before, this is transfer: its points count as
activated). Every later evaluation of an active type's check adds a labelled point: feasible when
the check passes, infeasible when it fails the same way. Before any failure, `prematch` asks
`types/match` about every graph this task could produce (each check x each culprit the world may
report), so types that earlier tasks learned guide the very first expansions.

Points go out in one batch per rollout on a background thread; only `match` and `suggest` block
the search, and their time is `kb_s`.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Protocol

from client.errors import BadRequest
from contract.models import (
    MAX_PENDING_REPORT,
    MAX_WATCHED_TYPES,
    Constraint,
    Graph,
    MatchResult,
    ModelsOut,
    PointIn,
    Source,
    SuggestIn,
    SuggestOut,
    TypeDetail,
    Value,
)
from planner.config import KnowledgeConfig
from planner.failures import Encodings, FailureGraph, failure_graph, size_constants
from planner.knowledge.found import FoundBindings
from planner.knowledge.live import LiveFeed, PeerHints, PendingExchange, joined_hints
from planner.knowledge.local import LocalSurrogates, PriorSettings
from planner.knowledge.poster import PointPoster
from planner.skeleton import DecisionVar
from planner.world import BindingWorld, CheckResult, TransitionOutcome


class KnowledgeClient(Protocol):
    """The calls of `client.CpkbClient` the planner needs."""

    def post_points(self, kb: str, points: Sequence[PointIn]) -> Any: ...

    def match_types(self, kb: str, graphs: Sequence[Graph]) -> list[MatchResult]: ...

    def suggest(self, kb: str, request: SuggestIn) -> SuggestOut: ...

    def models(
        self, kb: str, type_ids: Sequence[str], known: dict[str, str] | None = None
    ) -> ModelsOut: ...

    def get_type(self, kb: str, type_id: str) -> TypeDetail: ...


Key = tuple[int, int, str | None]  # (transition index, call index, culprit body)
SETTLED = frozenset({"ready", "prior", "error"})  # a type's fit states with no fit under way


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


@dataclass
class KnowledgeStats:
    types_activated: int = 0
    points_activated: int = 0
    types_active: int = 0
    suggestions: int = 0
    local_suggestions: int = 0  # of `suggestions`, answered in this process
    model_fetches: int = 0
    kb_s: float = 0.0
    kb_parts: dict[str, float] = field(default_factory=dict)  # kb_s by what it waited for
    # This thread's CPU time in suggestions (a model fetch's CPU included, which kb_parts
    # counts apart): below kb_parts["suggest"] by the waits, for its core (other processes) and
    # for the GIL (this process's other threads).
    suggest_cpu_s: float = 0.0
    errors: int = 0
    prematched: int = 0
    live_points: int = 0  # other planners' points taken in during the run
    live_types: int = 0  # types other planners created during the run, activated from them
    pending_shared: int = 0  # other planners' pending suggestions local ones were kept from
    peer_hints: int = 0  # other planners' feasible points scored as candidates (`PeerHints`)
    stored_hints: int = 0  # earlier runs' feasible points read as candidates at the start
    found_followed: int = 0  # other runs' found bindings this run followed (`FoundBindings`)
    explored: int = 0  # continuous values cp-bo took space-filling instead of its proposal
    events: dict[str, int] = field(default_factory=dict)

    def spent(self, part: str, seconds: float) -> None:
        """Count `seconds` of blocking on the knowledge base, under `part` (match, post, fetch,
        suggest): where a guided rollout's extra time goes."""
        self.kb_s += seconds
        self.kb_parts[part] = self.kb_parts.get(part, 0.0) + seconds

    def event(self, message: str) -> None:
        """Count a problem; distinct messages are kept (a few), repeats only counted."""
        self.errors += 1
        if message in self.events or len(self.events) < 10:
            self.events[message] = self.events.get(message, 0) + 1


def _never() -> float:
    """A clock that stands still: pending suggestions leave only when a point answers them."""
    return 0.0


def _settled(detail: TypeDetail) -> bool:
    """The type's fit holds every point the service has of it."""
    state = detail.surrogate
    return state is not None and state.status in SETTLED and state.n_fitted == detail.n_points


@lru_cache(maxsize=16)
def _task_graphs(skeleton: str, encodings: Encodings) -> dict[Key, FailureGraph]:
    """The failure graphs of one skeleton (by its repr) and its encodings, shared by the
    sessions of a process. A graph depends only on these, the check and the culprit, and a
    planner process (a bench worker, a planner loop) plans one task many times, and building
    every graph prematch looks up costs a share of a short run."""
    return {}


class KnowledgeSession:
    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        world: BindingWorld,
        *,
        run: str | None = None,
        worker: str | None = None,
        background: bool = True,
        lookahead: bool = True,
        local: bool = True,
        config: KnowledgeConfig | None = None,
    ) -> None:
        self.client = client
        self.config = config if config is not None else KnowledgeConfig()
        background = background and not self.config.deterministic
        self.lookahead = lookahead
        self.kb = kb
        self.world = world
        self.skeleton = world.skeleton
        self._domains = {d.var: d.domain for d in self.skeleton.decisions}
        self.run = run or uuid.uuid4().hex[:16]
        self.worker = worker
        self.stats = KnowledgeStats()
        self.poster = PointPoster(
            lambda pts: client.post_points(kb, pts),
            background=background,
            linger_s=self.config.post_linger_ms / 1000.0,
        )
        self._encodings = Encodings(
            world.geometry,
            square_grasps=self.config.square_grasps,
            grasp_symmetry=self.config.grasp_symmetry,
            metric_frames=self.config.metric_frames,
            relative_pairs=self.config.relative_pairs,
            periodic_headings=self.config.periodic_headings,
            body_sizes=self.config.body_sizes,
            size_inputs=self.config.size_inputs,
            movable_names=self.config.movable_names,
        )
        # Inputs of the models that are not decisions: in every point, fixed in every request.
        self._constants: dict[str, Value] = (
            dict(size_constants(world.geometry)) if self.config.size_inputs else {}
        )
        self._graphs = _task_graphs(repr(self.skeleton), self._encodings)
        self._active: dict[Key, Activation] = {}
        self._by_check: dict[tuple[int, int], list[tuple[Key, Activation]]] = {}
        self._pending: list[tuple[Key, FailureGraph, dict[str, Value], bool]] = []
        self.local = (
            LocalSurrogates(
                lambda ids, known: client.models(kb, ids, known),
                background=background,
                refresh_rollouts=self.config.refresh_rollouts,
                prior=PriorSettings.of(self.config),
                spread_walls=self.config.spread_walls,
                model_evidence=self.config.model_evidence,
                model_evidence_prior=self.config.model_evidence_prior,
                # A lifetime in wall time would make a run's course depend on its waits.
                pending_clock=_never if self.config.deterministic else time.monotonic,
            )
            if local and hasattr(client, "models")
            else None
        )
        live = self.config.live_points and not self.config.deterministic
        self.live = (
            LiveFeed(
                lambda ids, after: client.points_since(kb, ids, after, exclude_run=self.run),
                every_rollouts=self.config.live_every_rollouts,
                idle_max=self.config.live_idle_max,
                background=background,
            )
            if live and self.local is not None and hasattr(client, "points_since")
            else None
        )
        self.shared = (
            PendingExchange(
                lambda served, ids: client.exchange_pending(kb, self.run, served, ids).pending,
                every_rollouts=self.config.live_every_rollouts,
                background=background,
            )
            if self.live is not None
            and self.config.live_pending
            and hasattr(client, "exchange_pending")
            else None
        )
        self.hints = (
            PeerHints(
                self.config.live_hints,
                self.config.live_hints_limit,
                whole_only=self.config.live_hints_whole_only,
            )
            if self.live is not None and self.config.live_hints > 0
            else None
        )
        self.found = (
            FoundBindings(
                client,
                kb,
                task=world.name,
                skeleton=self.skeleton,
                run=self.run,
                live=live,
                every_rollouts=self.config.live_every_rollouts,
                idle_max=self.config.live_idle_max,
                background=background,
                on_error=self.stats.event,
            )
            if self.config.follow_found and hasattr(client, "bindings")
            else None
        )
        self.stored = (
            PeerHints(
                self.config.stored_hints,
                self.config.live_hints_limit,
                whole_only=self.config.stored_hints_prefer == "whole",
                prefer=self.config.stored_hints_prefer != "none",
            )
            if self.local is not None and self.config.stored_hints > 0
            else None
        )
        self._unmatched: dict[Key, FailureGraph] = {}
        self._absent: dict[Key, str] = {}  # graphs prematch found absent: their type IDs
        self._types: set[str] = set()
        self._rollout = 0

    # -- activation ---------------------------------------------------------------------------

    def prematch(self) -> None:
        """Activate the known types among every graph this task could produce."""
        candidates = (None, *getattr(self.world, "culprit_candidates", ()))
        for t, layer in enumerate(self.skeleton.transitions):
            for call in layer.calls:
                for culprit in candidates:
                    key = (t, layer.calls.index(call), culprit)
                    fg = self._graph(key, t, CheckResult(call, False), culprit)
                    if fg.bind:
                        self._unmatched[key] = fg
        found = self._match(only_existing=True)
        self.stats.prematched = found
        self._take_stored_hints()
        if self.live is not None:
            self.live.start()  # what is stored by now is in the models this run fetches
        if self.found is not None:
            self.found.start()

    def _take_stored_hints(self) -> None:
        """Keep the stored feasible points of the types prematch found (`stored_hints`)."""
        if self.stored is None or not self._types:
            return
        if not hasattr(self.client, "stored_feasible"):
            return
        started = time.perf_counter()
        try:
            answer = self.client.stored_feasible(
                self.kb, sorted(self._types)[:MAX_WATCHED_TYPES], self.config.stored_hints
            )
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self.stats.event(f"stored hints failed: {exc}")
            return
        finally:
            self.stats.spent("match", time.perf_counter() - started)
        for point in answer.points:
            self.stored.add(point, by_rollout=True)
        self.stats.stored_hints = len(answer.points)

    def _graph(self, key: Key, t: int, check: CheckResult, culprit: str | None) -> FailureGraph:
        if key not in self._graphs:
            self._graphs[key] = failure_graph(self.skeleton, t, check, culprit, self._encodings)
        return self._graphs[key]

    def _match(self, *, only_existing: bool) -> int:
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
            chunk = self.config.match_chunk
            for start in range(0, len(graphs), chunk):
                results.extend(self.client.match_types(self.kb, graphs[start : start + chunk]))
        except BadRequest:
            results = [self._match_one(graph) for graph in graphs]
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self.stats.event(f"match failed: {exc}")
            return 0
        finally:
            self.stats.spent("match", time.perf_counter() - started)
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

    def _match_one(self, graph: Graph) -> MatchResult | None:
        """One graph alone, so that a graph the service rejects does not block the others."""
        try:
            return self.client.match_types(self.kb, [graph])[0]
        except BadRequest as exc:
            self.stats.event(f"graph rejected: {exc}")
            return None

    def _activate(self, key: Key, fg: FailureGraph, result: MatchResult) -> None:
        transferred = result.exists and result.n_points > 0
        stored_with = 0 if result.exists else self.poster.submitted + 1
        if stored_with and self.local is not None:
            space = {
                n.label: n.domain
                for n in fg.graph.nodes
                if n.role == "decision" and n.domain is not None  # a decision's is never None
            }
            if self.local.adopt(result.type_id, space, stored_with):
                stored_with = 0  # no need to wait for the service to store it
        activation = Activation(result.type_id, fg, transferred, result.n_points, stored_with)
        self._active[key] = activation
        self._by_check.setdefault(fg.check, []).append((key, activation))
        if result.type_id in self._types:
            return  # the same type at one more check: counted once
        self._types.add(result.type_id)
        self.stats.types_active += 1
        if transferred:
            self.stats.types_activated += 1
            self.stats.points_activated += result.n_points

    # -- observing the search -----------------------------------------------------------------

    def on_transition(
        self, index: int, bindings: dict[str, Value], outcome: TransitionOutcome, rollout: int
    ) -> None:
        self._rollout = rollout
        values = {**bindings, **self._constants} if self._constants else bindings
        for position, check in enumerate(outcome.checks):
            if check.ok:
                for key, activation in self._by_check.get((index, position), ()):
                    x = activation.failure.x(values)
                    self._pending.append((key, activation.failure, x, True))
                continue
            culprit = check.culprits[0].body if check.culprits else None
            key = (index, position, culprit)
            fg = self._graph(key, index, check, culprit)
            if not fg.bind:
                continue
            self._pending.append((key, fg, fg.x(values), False))
            if key not in self._active:
                self._unmatched[key] = fg

    def on_rollout_end(self, rollout: int) -> None:
        """Activate the types of failures met for the first time, then post this rollout's
        points in one batch (in the background)."""
        self._match(only_existing=False)
        source = Source(task=self.world.name, run=self.run, rollout=rollout, worker=self.worker)
        points = [
            PointIn(
                graph=fg.graph,
                x=x,
                feasible=feasible,
                source=source,
                key=f"{self.run}:{rollout}:{i}",
            )
            for i, (_, fg, x, feasible) in enumerate(self._pending)
        ]
        batch = self.poster.submit(points)
        if self.local is not None:
            for key, _, x, feasible in self._pending:
                if key in self._active:
                    self.local.note(self._active[key].type_id, x, feasible, batch)
        self._take_live(rollout)
        if self.found is not None:
            self.found.tick(rollout)
        if self.config.deterministic:
            self._wait_for_fits(
                {self._active[k].type_id for k, *_ in self._pending if k in self._active}
            )
        self._pending = []

    def _take_live(self, rollout: int) -> None:
        """Weigh in the other planners' points a poll brought, activate the types they created
        among the graphs prematch found absent, and poll again if due."""
        if self.live is None or self.local is None:
            return
        absent = set(self._absent.values()) - self._types
        watched = [*sorted(self._types), *sorted(absent)][:MAX_WATCHED_TYPES]
        try:
            points = self.live.tick(rollout, watched)
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self.stats.event(f"live points failed: {exc}")
            return
        born: dict[str, int] = {}
        for point in points:
            if self.hints is not None:
                self.hints.add(point)
            if point.type_id in self._types:
                self.local.learn(point.type_id, point.point_id, point.x, point.feasible)
            else:
                born[point.type_id] = born.get(point.type_id, 0) + 1
        self.stats.live_points += len(points)
        for key, type_id in [(k, t) for k, t in self._absent.items() if t in born]:
            del self._absent[key]
            if type_id not in self._types:
                self.stats.live_types += 1
            created = MatchResult(type_id=type_id, exists=True, n_points=born[type_id])
            self._activate(key, self._graphs[key], created)
        self._share_pending(rollout)

    def _share_pending(self, rollout: int) -> None:
        """Report this run's pending suggestions; take in the other runs' that came back."""
        if self.shared is None or self.local is None:
            return
        local = self.local
        try:
            others = self.shared.tick(
                rollout,
                lambda: local.served(MAX_PENDING_REPORT),
                sorted(self._types)[:MAX_WATCHED_TYPES],
            )
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self.stats.event(f"sharing pending suggestions failed: {exc}")
            return
        if others is not None:
            self.local.share(others)

    def _wait_for_fits(self, type_ids: set[str]) -> None:
        """Block until the service has fitted every point of these types (deterministic mode):
        which fit a later suggestion sees, and what each fit starts warm from, then no longer
        depend on timing."""
        started = time.perf_counter()
        try:
            waiting = set(type_ids)
            while waiting:
                waiting = {t for t in waiting if not _settled(self.client.get_type(self.kb, t))}
                if waiting and time.perf_counter() - started > self.config.fit_wait_s:
                    self.stats.event("a fit took longer than knowledge.fit_wait_s")
                    return
                if waiting:
                    time.sleep(0.01)
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self.stats.event(f"waiting for a fit failed: {exc}")
        finally:
            self.stats.spent("fit", time.perf_counter() - started)

    # -- guiding the search -------------------------------------------------------------------

    def next_chain(self) -> dict[str, Value] | None:
        """A binding list another run of this task found, to follow now (each once)."""
        if self.found is None:
            return None
        chain = self.found.next()
        self.stats.found_followed = self.found.followed
        return chain

    def add_found(self, bindings: dict[str, Value], rollout: int) -> None:
        """Store the binding list this run found, for the other runs of its task."""
        if self.found is None:
            return
        started = time.perf_counter()
        self.found.store(bindings, rollout)
        self.stats.spent("post", time.perf_counter() - started)

    def constraints_at(self, var: str, path: dict[str, Value]) -> list[Constraint]:
        """The active types that constrain this decision: those whose decision vertexes include
        it, with earlier ones (fixed on this path); with `lookahead`, also later ones (optimised
        jointly, so that this decision leaves a feasible continuation: a grasp that no placement
        can follow is avoided at the grasp), and then every type on those later decisions, so
        that the continuation is feasible as a whole (pack's first box leaves room for the second
        and the third side by side, not for each of them on the same spot)."""
        known = {*path, *self._constants, var}
        chosen = [a for a in self._active.values() if var in a.vars]
        if self.lookahead:
            reached = {v for a in chosen for v in a.vars} | known
            ahead = reached - known
            rest = [a for a in self._active.values() if var not in a.vars]
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
            if activation.stored_with > self.poster.done:
                # A type met in this run exists once its first point is stored: wait for that
                # batch, so that when a type starts guiding does not depend on timing (unless
                # this process's own models took it up at once: `LocalSurrogates.adopt`).
                started = time.perf_counter()
                self.poster.wait_for(activation.stored_with)
                self.stats.spent("post", time.perf_counter() - started)
            bind = tuple(sorted(activation.failure.bind.items()))
            if (activation.type_id, bind) in seen:
                continue
            seen.add((activation.type_id, bind))
            constraints.append(Constraint(type_id=activation.type_id, bind=dict(bind)))
        return constraints

    def suggest(
        self,
        var: DecisionVar,
        path: dict[str, Value],
        siblings: Sequence[Value],
        constraints: list[Constraint],
        seed: int,
        *,
        n: int = 1,
    ) -> SuggestOut | None:
        """The MPF suggestion of the service (with `n > 1`, a batch of spread points), or None
        if the service could not answer."""
        bound = {v for c in constraints for v in c.bind.values()} - {var.var}
        given = {**self._constants, **path}
        later = sorted(bound - set(given))
        request = SuggestIn(
            space={var.var: var.domain} | {v: self._domains[v] for v in later},
            fixed={v: given[v] for v in sorted(bound & set(given))},
            constraints=constraints,
            exclude=[{var.var: value} for value in siblings],
            lookahead=later,
            seed=seed,
            n=n,
        )
        started, cpu_started = time.perf_counter(), time.thread_time()
        fetching = self.local.fetch_s if self.local is not None else 0.0
        try:
            answer = self._suggest_locally(request)
            if answer is None:
                answer = self.client.suggest(self.kb, request)
        except Exception as exc:  # fall back to space filling rather than stop the search
            self.stats.event(f"suggest failed: {exc}")
            return None
        finally:
            fetched = (self.local.fetch_s if self.local is not None else fetching) - fetching
            self.stats.spent("fetch", fetched)
            self.stats.spent("suggest", time.perf_counter() - started - fetched)
            self.stats.suggest_cpu_s += time.thread_time() - cpu_started
        self.stats.suggestions += 1
        return answer

    def _suggest_locally(self, request: SuggestIn) -> SuggestOut | None:
        """The answer from this process's copies of the models; None (ask the service, which
        says what is wrong) when that fails."""
        local = self.local
        if local is None:
            return None
        fetches = local.fetches
        try:
            hints = joined_hints(self.hints, self.stored)
            answer = local.suggest(request, self._rollout, self.poster.done, hints)
        except Exception as exc:
            # The service answers this one call (it says what was wrong with a request); the
            # next one is tried here again, so a passing network error changes nothing for good.
            self.stats.event(f"local suggestion failed, the service answers instead: {exc}")
            return None
        finally:
            self.stats.model_fetches += local.fetches - fetches
        self.stats.local_suggestions += 1
        return answer

    def close(self) -> None:
        """Post what is left and wait for the background poster. This comes after the search
        has its binding, so its time is kept apart (`kb_parts["close"]`), not in `kb_s`."""
        started = time.perf_counter()
        if self._pending:
            self.on_rollout_end(self._rollout)
        self.poster.close()
        if self.live is not None:
            self.live.close()
        if self.found is not None:
            self.found.close()
        if self.shared is not None:
            try:
                self.shared.close()
            except Exception as exc:  # its entries expire in the service anyway
                self.stats.event(f"withdrawing pending suggestions failed: {exc}")
        if self.local is not None:
            self.local.close()
            self.stats.pending_shared = self.local.shared_used
        if self.hints is not None:
            self.stats.peer_hints = self.hints.used
        self.stats.kb_parts["close"] = time.perf_counter() - started

    @property
    def points_posted(self) -> int:
        return self.poster.posted

"""Guidance: what the search is told, from this process's copies of the models, other planners'
feasible points (hints) and the bindings other runs of the task found.

A suggestion is answered here from the service's model snapshots (`LocalSurrogates`), the hints
scored among its candidates, or by the service where the planner does not maximise MPF itself
(`--suggest-in service`) or the local answer fails. Found bindings are handed to the tree, each
once, as its next rollout.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

from contract import models as wire
from contract.models import Constraint, LivePoint, SuggestIn, SuggestOut, Value
from planner.knowledge.client import KnowledgeClient
from planner.knowledge.found import FoundBindings
from planner.knowledge.live import PeerHints
from planner.knowledge.local import LocalSurrogates
from planner.knowledge.stats import KnowledgeStats
from planner.skeleton import DecisionVar


class Guidance:
    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        stats: KnowledgeStats,
        *,
        local: LocalSurrogates | None,
        hints: PeerHints | None,
        found: FoundBindings | None,
    ) -> None:
        self._client, self._kb, self._stats = client, kb, stats
        self.local, self.hints, self.found = local, hints, found

    def adopt(
        self,
        type_id: str,
        space: Mapping[str, wire.CategoricalDomain | wire.ContinuousDomain],
        stored_with: int,
    ) -> bool:
        """Guide at once from this run's own points of a type it is creating (see
        `LocalSurrogates.adopt`); False: wait for the service to store it."""
        return self.local is not None and self.local.adopt(type_id, space, stored_with)

    def note(self, type_id: str, x: dict[str, Value], feasible: bool, batch: int) -> None:
        """A point this run posted (in poster batch `batch`)."""
        if self.local is not None:
            self.local.note(type_id, x, feasible, batch)

    def learn(self, point: LivePoint, active: bool) -> None:
        """A point another planner stored: a hint if feasible, and weighed into its type's
        model if the type is `active` here."""
        if self.hints is not None:
            self.hints.add(point)
        if active and self.local is not None:
            self.local.learn(point.type_id, point.point_id, point.x, point.feasible)

    def next_chain(self) -> dict[str, Value] | None:
        """A binding list another run of this task found, to follow now (each once)."""
        if self.found is None:
            return None
        chain = self.found.next()
        self._stats.found_followed = self.found.followed
        return chain

    def store_found(self, bindings: dict[str, Value], rollout: int) -> None:
        """Store the binding list this run found, for the other runs of its task."""
        if self.found is None:
            return
        started = time.perf_counter()
        self.found.store(bindings, rollout)
        self._stats.spent("post", time.perf_counter() - started)

    def suggest(
        self,
        request: SuggestIn,
        *,
        rollout: int,
        stored: int,
    ) -> SuggestOut | None:
        """The MPF suggestion for `request`, or None if neither this process nor the service
        could answer. `stored`: the last poster batch the service has taken in."""
        started, cpu_started = time.perf_counter(), time.thread_time()
        fetching = self.local.fetch_s if self.local is not None else 0.0
        try:
            answer = self._suggest_locally(request, rollout, stored)
            if answer is None:
                answer = self._client.suggest(self._kb, request)
        except Exception as exc:  # fall back to space filling rather than stop the search
            self._stats.event(f"suggest failed: {exc}")
            return None
        finally:
            fetched = (self.local.fetch_s if self.local is not None else fetching) - fetching
            self._stats.spent("fetch", fetched)
            self._stats.spent("suggest", time.perf_counter() - started - fetched)
            self._stats.suggest_cpu_s += time.thread_time() - cpu_started
        self._stats.suggestions += 1
        return answer

    def _suggest_locally(self, request: SuggestIn, rollout: int, stored: int) -> SuggestOut | None:
        """The answer from this process's copies of the models; None (ask the service, which
        says what is wrong) when that fails."""
        local = self.local
        if local is None:
            return None
        fetches = local.fetches
        try:
            hints = self.hints.for_request if self.hints is not None else None
            answer = local.suggest(request, rollout, stored, hints)
        except Exception as exc:
            # The service answers this one call (it says what was wrong with a request); the
            # next one is tried here again, so a passing network error changes nothing for good.
            self._stats.event(f"local suggestion failed, the service answers instead: {exc}")
            return None
        finally:
            self._stats.model_fetches += local.fetches - fetches
        self._stats.local_suggestions += 1
        return answer

    def close(self) -> None:
        if self.found is not None:
            self.found.close()
        if self.local is not None:
            self.local.close()
        if self.hints is not None:
            self._stats.peer_hints = self.hints.used


def suggest_request(
    var: DecisionVar,
    path: dict[str, Value],
    siblings: Sequence[Value],
    constraints: list[Constraint],
    domains: Mapping[str, wire.Domain],
    seed: int,
    n: int,
) -> SuggestIn:
    """The request for a value of `var` on `path`: the space of `var` and of the later
    decisions the constraints bind (looked ahead), the earlier ones fixed, the siblings
    excluded."""
    bound = {v for c in constraints for v in c.bind.values()} - {var.var}
    later = sorted(bound - set(path))
    return SuggestIn(
        space={var.var: var.domain} | {v: domains[v] for v in later},
        fixed={v: path[v] for v in sorted(bound & set(path))},
        constraints=constraints,
        exclude=[{var.var: value} for value in siblings],
        lookahead=later,
        seed=seed,
        n=n,
    )

"""Sharing: this run's points out (the background poster), other planners' points in (the live
feed), and in deterministic mode the wait for the fits this run's points ask for.

Points go out in one batch per rollout on a background thread. Each poll, like each post, is a
request read in a thread of the planner's process, which holds the GIL while it runs; so a poll
that brought nothing spaces out the next (`planner.knowledge.polls`).
"""

from __future__ import annotations

import time

from contract.models import MAX_WATCHED_TYPES, LivePoint, PointIn, TypeDetail
from planner.knowledge.client import KnowledgeClient
from planner.knowledge.live import LiveFeed
from planner.knowledge.poster import PointPoster
from planner.knowledge.stats import KnowledgeStats

SETTLED = frozenset({"ready", "prior", "error"})  # a type's fit states with no fit under way


def _settled(detail: TypeDetail) -> bool:
    """The type's fit holds every point the service has of it."""
    state = detail.surrogate
    return state is not None and state.status in SETTLED and state.n_fitted == detail.n_points


class Sharing:
    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        stats: KnowledgeStats,
        *,
        poster: PointPoster,
        live: LiveFeed | None,
        fit_wait_s: float,
    ) -> None:
        self._client, self._kb, self._stats = client, kb, stats
        self.poster, self.live = poster, live
        self._fit_wait_s = fit_wait_s

    def start(self) -> None:
        """Start the live feed: what is stored by now is in the models this run fetches."""
        if self.live is not None:
            self.live.start()

    def post(self, points: list[PointIn]) -> int:
        """Hand over one rollout's points; their poster batch."""
        return self.poster.submit(points)

    def wait_stored(self, batch: int) -> None:
        """Block until poster batch `batch` is stored."""
        if batch > self.poster.done:
            started = time.perf_counter()
            self.poster.wait_for(batch)
            self._stats.spent("post", time.perf_counter() - started)

    def poll(self, rollout: int, watched: list[str]) -> list[LivePoint]:
        """Other planners' points a poll brought (and a new poll, if due)."""
        if self.live is None:
            return []
        try:
            points = self.live.tick(rollout, watched[:MAX_WATCHED_TYPES])
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self._stats.event(f"live points failed: {exc}")
            return []
        self._stats.live_points += len(points)
        return points

    def wait_for_fits(self, type_ids: set[str]) -> None:
        """Block until the service has fitted every point of these types (deterministic mode):
        which fit a later suggestion sees, and what each fit starts warm from, then no longer
        depend on timing."""
        started = time.perf_counter()
        try:
            waiting = set(type_ids)
            while waiting:
                waiting = {t for t in waiting if not _settled(self._client.get_type(self._kb, t))}
                if waiting and time.perf_counter() - started > self._fit_wait_s:
                    self._stats.event("a fit took longer than knowledge.fit_wait_s")
                    return
                if waiting:
                    time.sleep(0.01)
        except Exception as exc:  # a knowledge-base outage must not stop the search
            self._stats.event(f"waiting for a fit failed: {exc}")
        finally:
            self._stats.spent("fit", time.perf_counter() - started)

    def close(self) -> None:
        """Post what is queued and stop polling."""
        self.poster.close()
        if self.live is not None:
            self.live.close()
        self._stats.points_posted = self.poster.posted
        self._stats.kb_errors += self.poster.failed

"""Binding lists found by runs of one task, shared through the knowledge base.

A planner that solves its task stores the binding list (`POST /v1/kbs/{kb}/bindings`). The other
runs of the same task (its name and a digest of its plan skeleton, so that the decisions mean
the same) read them, those stored before when they start and, with `live`, the newer ones every
few rollouts in the background, and hand each once, the newest first, to the tree, which follows
it as its next rollout (`knowledge.follow_found`). A peer's feasible points reach a planner as
hints, and a hint only changes a node that widens; the root of a grown tree seldom does, so a
binding another planner found would otherwise wait there for many rollouts.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

from contract.bindings import BindingIn, BindingsPage
from contract.models import MAX_LABEL, Value
from planner.knowledge.client import KnowledgeClient
from planner.knowledge.polls import PollSchedule
from planner.skeleton import Skeleton


def skeleton_digest(skeleton: Skeleton) -> str:
    return hashlib.sha256(repr(skeleton).encode()).hexdigest()


class FoundBindings:
    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        *,
        task: str,
        skeleton: Skeleton,
        run: str,
        live: bool,
        every_rollouts: int = 1,
        idle_max: int = 1,
        background: bool = True,
        on_error: Callable[[str], None] = lambda message: None,
    ) -> None:
        self._client, self._kb, self._run = client, kb, run
        self._task, self._skeleton = task[:MAX_LABEL], skeleton_digest(skeleton)
        self.live = live
        self.schedule = PollSchedule(every_rollouts, idle_max)
        self.schedule.polled(0)  # `start` reads what is stored when the run begins
        self._on_error = on_error
        self._cursor: int | None = None
        self._executor = (
            ThreadPoolExecutor(1, thread_name_prefix="cpkb-found") if live and background else None
        )
        self._in_flight: Future[BindingsPage] | None = None
        self._waiting: list[dict[str, Value]] = []
        self.followed = 0

    def start(self) -> None:
        """Read the bindings stored so far (this call waits for the answer)."""
        self._guarded(lambda: self._take(self._poll(None)))

    def tick(self, rollout: int) -> None:
        """Take in a finished poll; start the next one if it is due (with `live`; the first
        reads from the start if `start` did not)."""
        if self.live:
            self._guarded(lambda: self._tick(rollout))

    def next(self) -> dict[str, Value] | None:
        """The newest binding not handed out yet, or None."""
        if not self._waiting:
            return None
        self.followed += 1
        return self._waiting.pop()

    def store(self, bindings: dict[str, Value], rollout: int) -> None:
        """Store the binding list this run found, for the other runs of its task."""
        binding = BindingIn(
            task=self._task,
            skeleton=self._skeleton,
            run=self._run,
            rollout=rollout,
            bindings=bindings,
        )
        self._guarded(lambda: self._client.add_binding(self._kb, binding))

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        self._in_flight = None

    def _tick(self, rollout: int) -> None:
        poll = self._in_flight
        if poll is not None:
            if not poll.done():
                return
            self._in_flight = None
            self._answered(poll.result())
        if not self.schedule.due(rollout):
            return
        self.schedule.polled(rollout)
        if self._executor is None:
            self._answered(self._poll(self._cursor))
        else:
            self._in_flight = self._executor.submit(self._poll, self._cursor)

    def _poll(self, after: int | None) -> BindingsPage:
        return self._client.bindings(
            self._kb, skeleton=self._skeleton, task=self._task, after=after, exclude_run=self._run
        )

    def _answered(self, page: BindingsPage) -> None:
        self._take(page)
        self.schedule.answered(bool(page.bindings))

    def _take(self, page: BindingsPage) -> None:
        self._cursor = page.cursor if self._cursor is None else max(self._cursor, page.cursor)
        self._waiting += [found.bindings for found in page.bindings]

    def _guarded(self, call: Callable[[], object]) -> None:
        """A knowledge-base outage must not stop the search: it is an event of the run."""
        try:
            call()
        except Exception as exc:
            self._on_error(f"found bindings: {exc}")

"""When a planner's background polls of the knowledge base are due.

Each poll is an HTTP request answered in a thread of the planner's process, and that thread
takes the GIL from the search while it reads the answer. A planner alone on a knowledge base
polls for nothing on every rollout; so a poll that brings nothing may space the next ones out
(`knowledge.live_idle_max`), and the first that brings something restores the pace.
"""

from __future__ import annotations


class PollSchedule:
    """Due every `every` rollouts; after each empty answer the gap doubles, up to `idle_max`
    rollouts; an answer with anything in it sets it back to `every`."""

    def __init__(self, every: int, idle_max: int = 1) -> None:
        if every < 1:
            raise ValueError("a poll is due every 1 rollout or more")
        self.every = every
        self.idle_max = max(idle_max, every)
        self.gap = every
        self._last: int | None = None

    def due(self, rollout: int) -> bool:
        return self._last is None or rollout - self._last >= self.gap

    def polled(self, rollout: int) -> None:
        self._last = rollout

    def answered(self, anything: bool) -> None:
        self.gap = self.every if anything else min(2 * self.gap, self.idle_max)

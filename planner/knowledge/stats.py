"""What a knowledge session did in one run: counts and the time the search waited for the
knowledge base. A `PlanResult` holds it as it is (`planner.run`)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class KnowledgeStats:
    types_activated: int = 0  # types met that earlier runs had points of (transfer)
    points_activated: int = 0  # their points
    types_active: int = 0
    types_prematched: int = 0  # of types_activated, found before the search met their failure
    points_posted: int = 0
    suggestions: int = 0
    local_suggestions: int = 0  # of `suggestions`, answered in this process
    model_fetches: int = 0
    kb_errors: int = 0  # problems met (each noted in `events`) and points that failed to post
    live_points: int = 0  # other planners' points taken in during the run
    live_types: int = 0  # types other planners created during the run, activated from them
    peer_hints: int = 0  # other planners' feasible points scored as candidates (`PeerHints`)
    found_followed: int = 0  # other runs' found bindings this run followed (`FoundBindings`)
    kb_s: float = 0.0  # time the search blocked on the knowledge base
    kb_parts: dict[str, float] = field(default_factory=dict)  # kb_s by what it waited for
    # This thread's CPU time in suggestions (a model fetch's CPU included, which kb_parts
    # counts apart): below kb_parts["suggest"] by the waits, for its core (other processes) and
    # for the GIL (this process's other threads).
    suggest_cpu_s: float = 0.0
    events: dict[str, int] = field(default_factory=dict)  # distinct problems, with their counts

    def spent(self, part: str, seconds: float) -> None:
        """Count `seconds` of blocking on the knowledge base, under `part` (match, post, fetch,
        suggest, fit): where a guided rollout's extra time goes."""
        self.kb_s += seconds
        self.kb_parts[part] = self.kb_parts.get(part, 0.0) + seconds

    def event(self, message: str) -> None:
        """Count a problem; distinct messages are kept (a few), repeats only counted."""
        self.kb_errors += 1
        if message in self.events or len(self.events) < 10:
            self.events[message] = self.events.get(message, 0) + 1

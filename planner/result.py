"""What a binding search reports: its progress while it runs and its result at the end."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from contract.models import Value
from planner.knowledge.stats import KnowledgeStats


@dataclass(frozen=True)
class Progress:
    rollouts: int
    max_rollouts: int
    best_depth: float
    solved: bool
    types_active: int
    types_activated: int
    elapsed_s: float


@dataclass
class PlanResult:
    task: str
    method: str
    seed: int
    solved: bool
    rollouts: int
    rollouts_spent: int
    # wall_s: from loading the world to the search's end, the time to the binding, for every method
    wall_s: float
    sim_s: float
    sample_s: float
    bindings: dict[str, Value] | None
    best_depth: float
    time_budget_s: float | None = None  # the run's budget in seconds, if it had one
    timed_out: bool = False  # stopped by time_budget_s before the binding and the rollout cap
    # What the knowledge session did (zeros for a method without one)
    knowledge: KnowledgeStats = field(default_factory=KnowledgeStats)
    # CPU time of this process's other threads during the search (posting points, polls, model
    # refreshes): each holds the GIL while it runs, so the search waits for it
    background_cpu_s: float = 0.0
    kb: str | None = None
    run: str | None = None
    notes: list[str] = field(default_factory=list)
    config: dict[str, dict[str, Any]] = field(default_factory=dict)  # the whole PlanConfig

    def to_json(self) -> dict[str, Any]:
        """The `cpkb plan --json` dict: flat, the knowledge session's counts beside the run's
        (its events are in `notes`)."""
        out = asdict(self)
        knowledge = out.pop("knowledge")
        del knowledge["events"]
        knowledge["kb_parts"] = {
            part: round(s, 6) for part, s in sorted(knowledge["kb_parts"].items())
        }
        knowledge["suggest_cpu_s"] = round(knowledge["suggest_cpu_s"], 6)
        out.update(knowledge)
        for key in ("wall_s", "sim_s", "kb_s", "sample_s", "best_depth"):
            out[key] = round(out[key], 6)
        return out

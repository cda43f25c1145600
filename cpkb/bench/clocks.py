"""The wall time a user waits for a run's binding, on two clocks, and what each count includes.

A transfer run is its predecessors, a wait for their fits, then the target. The paper counts
the target alone; a user who starts in a fresh workspace waits for all of it. So every run
reports both clocks, from the parts the bench measures:

- `warm`: the target's own wall time (`wall_s`, from loading its world to its binding). The
  knowledge base was stocked and fitted before the clock started, as in a lab that has worked
  in the workspace before; its fits of the target's own points land inside the clock.
- `cold`: the predecessors' wall times, the wait for their fits (`fit_wait_s`) and the
  target's: a user starting afresh, whose predecessors run and are fitted inside the clock.

A method without predecessors reads the same on both. Rollouts count the target's alone, to
its first binding (the paper's metric); the predecessors' rollouts are reported beside them
(`predecessor_rollouts`), never summed in. A portfolio's (`cpkb.bench.portfolio`) sum its
trees' rollouts, and its clocks are its winner's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

Clock = Literal["warm", "cold"]
CLOCKS: tuple[Clock, ...] = ("warm", "cold")

COUNTS_NOTE = (
    "rollouts: the target's to its first binding (the cap if unsolved), summed over the trees "
    "of a portfolio; a transfer method's predecessor rollouts are shown beside them, not in "
    "them. wall warm: the target's own run, its knowledge base stocked and fitted before the "
    "clock starts. wall cold: the predecessors' runs, the wait for their fits and the target's "
    "run. A method without predecessors reads the same on both clocks."
)
"""What each count of a summary includes, printed under every summary table."""


def clock_s(record: Mapping[str, Any], clock: Clock) -> float:
    """The run's wall time on `clock` (runs recorded before the clocks were: from their
    parts, which every bench record holds)."""
    target = float(record["wall_s"])
    if clock == "warm":
        return target
    return (
        float(record.get("predecessor_wall_s") or 0.0)
        + float(record.get("fit_wait_s") or 0.0)
        + target
    )


def predecessor_rollouts(record: Mapping[str, Any]) -> int:
    """Every rollout the run's predecessors spent (their whole budgets)."""
    return sum(
        int(p.get("rollouts_spent") or p.get("rollouts") or 0)
        for p in record.get("predecessors") or ()
    )


def clock_fields(record: Mapping[str, Any]) -> dict[str, float | int]:
    """The fields a run records: both clocks and its predecessors' rollouts."""
    return {
        "clock_warm_s": clock_s(record, "warm"),
        "clock_cold_s": clock_s(record, "cold"),
        "predecessor_rollouts": predecessor_rollouts(record),
    }

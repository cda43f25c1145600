"""Where a bench's wall time goes, per task kind and method, against a baseline method.

A guided run pays for its suggestions and usually simulates more per rollout (its bindings get
past the cheap checks), so it is faster than the baseline only beyond some reduction in
rollouts. Per kind and method this prints the means per run (wall time, rollouts, simulation,
suggestions with their count and mean cost, and the planner's CPU time per request where the
runs recorded it, the rest: loading the world, the tree, the other knowledge-base calls, with
the CPU time the process's background threads took where recorded) and,
against the baseline, the wall ratio, the rollout reduction reached and the reduction at which
the wall times would be level (1 - the baseline's cost per rollout over the method's, both as
mean wall over mean rollouts). Report wall times of runs made with
`--workers 1` only; `--seeds` picks them out of a joined directory. The baseline is the
strongest search without learning unless `--baseline` names another; `--clock cold` reads each
run's cold clock (its predecessors' runs and the wait for their fits added, shown as their own
part), `warm` (default) the target's run alone (`cpkb.bench.clocks`).

    .venv/bin/python benchmarks/wall.py benchmarks/results/heldout23 --seeds 8400-8404
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cpkb.bench.clocks import CLOCKS, Clock, clock_s
from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import BASELINE_METHOD, seed_range, task_kinds
from cpkb.bench.stats import ordered, rollouts_metric


@dataclass(frozen=True)
class Cell:
    """Means per run of one method on one task kind."""

    runs: int
    wall_s: float
    rollouts: float
    sim_s: float
    suggest_s: float
    requests: float
    suggest_cpu_s: float | None = None  # None: runs from before `suggest_cpu_s` was recorded
    background_cpu_s: float | None = None  # None: runs from before it was recorded
    predecessor_s: float = 0.0  # on the cold clock: the predecessors' runs and their fits

    @property
    def rest_s(self) -> float:
        return self.wall_s - self.sim_s - self.suggest_s - self.predecessor_s

    @property
    def per_rollout_s(self) -> float:
        return self.wall_s / self.rollouts if self.rollouts else 0.0

    @property
    def request_s(self) -> float:
        return self.suggest_s / self.requests if self.requests else 0.0

    @property
    def request_cpu_s(self) -> float | None:
        """The planner thread's CPU time per request: below `request_s` by its waits for the
        core (other processes on it) and the GIL (this process's other threads)."""
        if self.suggest_cpu_s is None or not self.requests:
            return None
        return self.suggest_cpu_s / self.requests


def _suggest_s(record: dict) -> float:
    """Time in the knowledge base's suggestions (`kb_parts.suggest`, wherever MPF was
    maximised); a method that asks none, such as quasi-random, has no such part."""
    parts = record.get("kb_parts") or {}
    return float(parts.get("suggest", 0.0))


def _mean_of(records: list[dict], key: str) -> float | None:
    """The mean of a field every record holds; None where some run predates it."""
    if not all(key in r for r in records):
        return None
    return float(np.mean([r[key] for r in records]))


def cells(records: list[dict], clock: Clock = "warm") -> dict[tuple[str, str], Cell]:
    """(kind, method) -> its means on `clock`; "all" pools the kinds."""
    grouped: dict[tuple[str, str], list[dict]] = defaultdict(list)
    kinds = task_kinds({str(r["task"]) for r in records})
    for record in records:
        kind = kinds.get(str(record["task"]), str(record["task"]))
        grouped[(kind, record["method"])].append(record)
        grouped[("all", record["method"])].append(record)
    return {
        key: Cell(
            runs=len(found),
            wall_s=float(np.mean([clock_s(r, clock) for r in found])),
            rollouts=float(np.mean([rollouts_metric(r) for r in found])),
            sim_s=float(np.mean([r["sim_s"] for r in found])),
            suggest_s=float(np.mean([_suggest_s(r) for r in found])),
            requests=float(np.mean([r.get("suggestions", 0) for r in found])),
            suggest_cpu_s=_mean_of(found, "suggest_cpu_s"),
            background_cpu_s=_mean_of(found, "background_cpu_s"),
            predecessor_s=float(np.mean([clock_s(r, clock) - r["wall_s"] for r in found])),
        )
        for key, found in grouped.items()
    }


def table(found: dict[tuple[str, str], Cell], baseline: str) -> list[str]:
    """Markdown rows, kinds in order with "all" last, the baseline first within a kind."""
    lines = [
        "| kind | method | runs | wall | rollouts | simulation | suggestions (requests x cost)"
        " | rest | per rollout | wall / baseline | rollouts saved | level at |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    kinds = sorted({kind for kind, _ in found}, key=lambda k: (k == "all", k))
    for kind in kinds:
        base = found.get((kind, baseline))
        methods = ordered((m for k, m in found if k == kind), [baseline])
        for method in methods:
            cell = found[(kind, method)]
            against = ["-", "-", "-"]
            if base is not None and method != baseline and base.wall_s and base.rollouts:
                saved = 1.0 - cell.rollouts / base.rollouts
                level = 1.0 - base.per_rollout_s / cell.per_rollout_s if cell.rollouts else 0.0
                against = [f"{cell.wall_s / base.wall_s:.2f}", f"{saved:.0%}", f"{level:.0%}"]
            cpu, background = cell.request_cpu_s, cell.background_cpu_s
            cost = f"{1000 * cell.request_s:.1f} ms" + (
                f", CPU {1000 * cpu:.1f} ms" if cpu is not None else ""
            )
            rest = f"{cell.rest_s:.2f} s" + (
                f" (background CPU {background:.3f} s)" if background else ""
            )
            if cell.predecessor_s:
                rest += f" + predecessors and their fits {cell.predecessor_s:.2f} s"
            lines.append(
                f"| {kind} | {method} | {cell.runs} | {cell.wall_s:.2f} s | {cell.rollouts:.1f} "
                f"| {cell.sim_s:.2f} s | {cell.suggest_s:.2f} s ({cell.requests:.1f} x {cost}) "
                f"| {rest} "
                f"| {1000 * cell.per_rollout_s:.1f} ms | {' | '.join(against)} |"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="a bench's --out directory")
    parser.add_argument("--baseline", default=BASELINE_METHOD, help=f"(default {BASELINE_METHOD})")
    parser.add_argument(
        "--clock", choices=CLOCKS, default="warm", help="the wall clock read (default warm)"
    )
    parser.add_argument("--seeds", type=seed_range, help="only these seeds, e.g. 8000-8004")
    args = parser.parse_args(argv)
    records = ResultStore(args.results).records()
    if args.seeds is not None:
        records = [r for r in records if int(r["seed"]) in args.seeds]
    if not records:
        print(f"no runs in {args.results} for those seeds", file=sys.stderr)
        return 2
    print("\n".join(table(cells(records, args.clock), args.baseline)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

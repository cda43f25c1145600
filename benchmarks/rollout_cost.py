"""What a rollout costs per method, against the baseline's, from a bench's runs.

The issue's bound (a guided rollout at most 2x a quasi-random one) is about rollouts actually
run, so each run counts the rollouts it ran (to its binding, or to its budget: a run stopped by
`--time-budget` ran fewer than the cap that its "rollouts to the first binding" counts). Per task
kind and method: runs, rollouts run, and per rollout the wall time, the simulation, the
planner's suggestions (wall and CPU), prematch and other matching, the rest; then the ratio of
the wall per rollout to the baseline's. Means of totals (sum over runs / rollouts over runs), so
a long run weighs by its rollouts. Compare within one bench with `--workers 1` only: the wall
times of a loaded machine scale every part.

    .venv/bin/python benchmarks/rollout_cost.py benchmarks/results/dev-hard
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import BASELINE_METHOD, task_kinds
from cpkb.bench.stats import ordered

PARTS = ("wall_s", "sim_s", "suggest_s", "suggest_cpu_s", "match_s")


def _parts(record: Mapping[str, Any]) -> dict[str, float]:
    kb = record.get("kb_parts") or {}
    return {
        "wall_s": float(record["wall_s"]),
        "sim_s": float(record["sim_s"]),
        "suggest_s": float(kb.get("suggest", 0.0)),
        "suggest_cpu_s": float(record.get("suggest_cpu_s") or 0.0),
        "match_s": float(kb.get("match", 0.0)),
    }


def per_rollout(records: Iterable[Mapping[str, Any]]) -> dict[tuple[str, str], dict[str, float]]:
    """(kind, method) -> runs, rollouts run, and each part's ms per rollout run."""
    records = list(records)
    kinds = task_kinds({r["task"] for r in records})
    totals: dict[tuple[str, str], dict[str, float]] = defaultdict(lambda: defaultdict(float))
    for r in records:
        for kind in (kinds.get(r["task"], r["task"]), "all"):
            cell = totals[(kind, r["method"])]
            cell["runs"] += 1
            cell["rollouts"] += int(r["rollouts"])
            for part, value in _parts(r).items():
                cell[part] += value
    cells = {}
    for key, cell in totals.items():
        done = max(cell["rollouts"], 1.0)
        ms = {part: 1000.0 * cell[part] / done for part in PARTS}
        rest = ms["wall_s"] - ms["sim_s"] - ms["suggest_s"] - ms["match_s"]
        cells[key] = {"runs": cell["runs"], "rollouts": cell["rollouts"], **ms, "rest_s": rest}
    return cells


def table(cells: Mapping[tuple[str, str], Mapping[str, float]], methods: list[str]) -> str:
    lines = [
        "| kind | method | runs | rollouts run | ms per rollout: wall | simulation | suggestions "
        "(CPU) | matching | rest | wall per rollout / baseline's |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    kinds = sorted({k for k, _ in cells}, key=lambda k: (k == "all", k))
    for kind in kinds:
        base = cells.get((kind, BASELINE_METHOD))
        for method in ordered((m for k, m in cells if k == kind), methods):
            c = cells[(kind, method)]
            ratio = (
                "-"
                if base is None or method == BASELINE_METHOD
                else (f"{c['wall_s'] / base['wall_s']:.2f}")
            )
            lines.append(
                f"| {kind} | {method} | {c['runs']:.0f} | {c['rollouts']:.0f} | "
                f"{c['wall_s']:.1f} | {c['sim_s']:.1f} | {c['suggest_s']:.1f} "
                f"({c['suggest_cpu_s']:.1f}) | {c['match_s']:.1f} | {c['rest_s']:.1f} | {ratio} |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="a bench's --out directory")
    parser.add_argument("--methods", default="", help="the order of the rows, comma-separated")
    args = parser.parse_args(argv)
    records = ResultStore(args.results).records()
    if not records:
        print(f"{args.results}: no runs", file=sys.stderr)
        return 2
    methods = [m for m in args.methods.split(",") if m] or [BASELINE_METHOD]
    print(table(per_rollout(records), methods))
    return 0


if __name__ == "__main__":
    sys.exit(main())

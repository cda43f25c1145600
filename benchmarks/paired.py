"""An A/B of two arms of one bench, paired by (target, seed), per task kind.

Guided runs are not repeatable per seed and their spread is wide, so arms are compared run for
run on the same (target, seed) pairs: the ratio of the mean rollouts (B / A, below 1: B took
fewer) with a paired bootstrap 95 % interval, and both medians. An arm may be several methods
joined by `+` (e.g. the default run twice as `cp-bo+cp-bo-walls`): their runs of one pair are
averaged, so the twin arms of a default count as one better-measured arm. A method written
`DIR:method` is taken from another bench's directory (planners at once against the same seeds
alone, an arm rerun elsewhere).

    .venv/bin/python benchmarks/paired.py benchmarks/results/heldout23 \
        quasi-random cp-bo-transfer
    .venv/bin/python benchmarks/paired.py benchmarks/results/concurrent23e/pack \
        alone/:cp-bo n8-found/:cp-bo
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import task_kinds
from cpkb.bench.stats import rollouts_metric
from cpkb.bench.together import ratio_ci


def pairs(records: list[dict], a: list[str], b: list[str]) -> dict[str, list[tuple[float, float]]]:
    """Per kind (and "all"): (mean of A's runs, mean of B's runs) of each (target, seed) that
    both arms ran. A task without a declared kind (a shipped task) is a kind of its own."""
    runs: dict[tuple[str, int], dict[str, float]] = defaultdict(dict)
    for record in records:
        runs[(record["task"], record["seed"])][record["method"]] = rollouts_metric(record)
    kinds = task_kinds({task for task, _ in runs})
    out: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for (task, _), by_method in sorted(runs.items()):
        in_a = [by_method[m] for m in a if m in by_method]
        in_b = [by_method[m] for m in b if m in by_method]
        if in_a and in_b:
            pair = (float(np.mean(in_a)), float(np.mean(in_b)))
            out[kinds.get(task, task)].append(pair)
            out["all"].append(pair)
    return out


def _elsewhere(results: Path, arm: str) -> list[dict]:
    """The runs of `DIR:method` (DIR relative to `results`), their method renamed to `arm`."""
    directory, method = arm.rsplit(":", 1)
    found = [r for r in ResultStore(results / directory).records() if r["method"] == method]
    return [{**record, "method": arm} for record in found]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="a bench's --out directory")
    parser.add_argument("a", help="arm A: a method or variant, or several joined by +")
    parser.add_argument("b", help="arm B, likewise")
    args = parser.parse_args(argv)
    records = ResultStore(args.results).records()
    for arm in {*args.a.split("+"), *args.b.split("+")}:
        if ":" in arm:
            records += _elsewhere(args.results, arm)
    if not records:
        print(f"no runs in {args.results}", file=sys.stderr)
        return 2
    print("| kind | pairs | A mean | B mean | B / A | 95 % CI | A median | B median |")
    print("|---|---|---|---|---|---|---|---|")
    found_by_kind = pairs(records, args.a.split("+"), args.b.split("+"))
    for kind in sorted(found_by_kind, key=lambda k: (k == "all", k)):
        found = found_by_kind[kind]
        a, b = np.array(found).T
        ci = ratio_ci(a, b)
        shown = f"[{ci[0]:.2f}, {ci[1]:.2f}]" if ci else "-"
        print(
            f"| {kind} | {len(a)} | {a.mean():.1f} | {b.mean():.1f} | {b.mean() / a.mean():.2f} "
            f"| {shown} | {np.median(a):.0f} | {np.median(b):.0f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""An A/B of two arms of one bench, paired by (target, seed), per task kind.

Guided runs are not repeatable per seed and their spread is wide, so arms are compared run for
run on the same (target, seed) pairs: the ratio of the mean rollouts (B / A, below 1: B took
fewer) with a paired bootstrap 95 % interval, the clustered one (targets resampled, then the
pairs within them: `cpkb.bench.clustered`), on how many targets B's mean was below A's, and
both medians. Given one arm, A is the strongest baseline (`quasi-random-restarts`); name
`quasi-random` as A for the comparison with the paper's figures. An arm may be several methods
joined by `+` (e.g. the default run twice as `cp-bo+cp-bo-walls`): their runs of one pair are
averaged, so the twin arms of a default count as one better-measured arm. A method written
`DIR:method` is taken from another bench's directory (planners at once against the same seeds
alone, an arm rerun elsewhere).

    .venv/bin/python benchmarks/paired.py benchmarks/results/dev-baselines cp-bo-transfer
    .venv/bin/python benchmarks/paired.py benchmarks/results/concurrent23e/pack \
        alone/:cp-bo n8-found/:cp-bo
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from cpkb.bench import clustered
from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import BASELINE_METHOD, task_kinds
from cpkb.bench.stats import rollouts_metric
from cpkb.bench.together import ratio_ci


def _paired_runs(
    records: list[dict], a: list[str], b: list[str]
) -> list[tuple[str, str, tuple[float, float]]]:
    """(kind, target, (mean of A's runs, mean of B's runs)) of each (target, seed) that both
    arms ran. A task without a declared kind (a shipped task) is a kind of its own."""
    runs: dict[tuple[str, int], dict[str, float]] = defaultdict(dict)
    for record in records:
        runs[(record["task"], record["seed"])][record["method"]] = rollouts_metric(record)
    kinds = task_kinds({task for task, _ in runs})
    out = []
    for (task, _), by_method in sorted(runs.items()):
        in_a = [by_method[m] for m in a if m in by_method]
        in_b = [by_method[m] for m in b if m in by_method]
        if in_a and in_b:
            out.append((kinds.get(task, task), task, (float(np.mean(in_a)), float(np.mean(in_b)))))
    return out


def pairs(records: list[dict], a: list[str], b: list[str]) -> dict[str, list[tuple[float, float]]]:
    """Per kind (and "all"): the (A, B) pair of each (target, seed) both arms ran."""
    out: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for kind, _, pair in _paired_runs(records, a, b):
        out[kind].append(pair)
        out["all"].append(pair)
    return out


def targets(records: list[dict], a: list[str], b: list[str]) -> dict[str, list[clustered.Target]]:
    """Per kind (and "all"): each target's pairs as (A's runs, B's runs), seed by seed."""
    split: dict[str, dict[str, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    for kind, task, pair in _paired_runs(records, a, b):
        split[kind][task].append(pair)
        split["all"][task].append(pair)
    return {
        kind: [(np.array(found)[:, 0], np.array(found)[:, 1]) for found in by_task.values()]
        for kind, by_task in split.items()
    }


def _elsewhere(results: Path, arm: str) -> list[dict]:
    """The runs of `DIR:method` (DIR relative to `results`), their method renamed to `arm`."""
    directory, method = arm.rsplit(":", 1)
    found = [r for r in ResultStore(results / directory).records() if r["method"] == method]
    return [{**record, "method": arm} for record in found]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="a bench's --out directory")
    parser.add_argument(
        "arms",
        nargs="+",
        metavar="ARM",
        help=f"[A] B: a method or variant, or several joined by +; A defaults to "
        f"{BASELINE_METHOD}, the strongest baseline",
    )
    args = parser.parse_args(argv)
    if len(args.arms) > 2:
        parser.error("give at most two arms, A and B")
    args.a, args.b = [BASELINE_METHOD, *args.arms][-2:]
    records = ResultStore(args.results).records()
    for arm in {*args.a.split("+"), *args.b.split("+")}:
        if ":" in arm:
            records += _elsewhere(args.results, arm)
    if not records:
        print(f"no runs in {args.results}", file=sys.stderr)
        return 2
    print(f"A: {args.a}, B: {args.b}")
    print(
        "| kind | pairs | A mean | B mean | B / A | 95 % CI (pairs) | 95 % CI (targets) "
        "| B beats A on | A median | B median |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    found_by_kind = pairs(records, args.a.split("+"), args.b.split("+"))
    by_target = targets(records, args.a.split("+"), args.b.split("+"))
    for kind in sorted(found_by_kind, key=lambda k: (k == "all", k)):
        found = found_by_kind[kind]
        a, b = np.array(found).T
        wins, count = clustered.beats(by_target[kind])
        shown = [_shown(ratio_ci(a, b)), _shown(clustered.ratio_ci(by_target[kind]))]
        print(
            f"| {kind} | {len(a)} | {a.mean():.1f} | {b.mean():.1f} | {b.mean() / a.mean():.2f} "
            f"| {' | '.join(shown)} | {wins}/{count} | {np.median(a):.0f} | {np.median(b):.0f} |"
        )
    return 0


def _shown(ci: tuple[float, float] | None) -> str:
    return f"[{ci[0]:.2f}, {ci[1]:.2f}]" if ci else "-"


if __name__ == "__main__":
    raise SystemExit(main())

"""The summary table: per (task, method) cell, rollouts and wall time against a baseline.

The baseline is the strongest search without learning (`quasi-random-restarts`) unless a
summary names the paper's (`quasi-random`, for the comparison with the paper's figures, whose
reductions are shown beside only then). An unsolved run counts as the rollout cap (also when
its search space ran out before the cap), as in the paper's Fig. 5, so a cell's mean is a lower
bound when its solved rate is below 1. Wall time is the time the run took, solved or not, on
both clocks (`cpkb.bench.clocks`). With a budget in seconds (`time_budget_s`), as TAMP papers
report (eTAMP: success rate and mean seconds per task), a run counts as solved only within it
and an unsolved run's time as the budget. A row that pools several targets (a kind, or all of
them) also gives the clustered interval (`cpkb.bench.clustered`: targets resampled, then seeds)
and on how many of its targets the method's mean beat the baseline's.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import mannwhitneyu

from cpkb.bench import clustered
from cpkb.bench.clocks import COUNTS_NOTE, clock_s, predecessor_rollouts
from cpkb.bench.scenarios import (
    BASELINE_METHOD,
    PAPER_BASELINE_METHOD,
    PAPER_REDUCTION_PERCENT,
    TRANSFER_METHODS,
)

ALL_KINDS = "all"
"""The row of a by-kind summary that pools every kind."""


@dataclass(frozen=True)
class CellSummary:
    """One row of the table. Reductions are percent of the baseline's mean (positive = fewer)."""

    task: str
    method: str
    n: int
    solved_rate: float
    rollouts_mean: float
    rollouts_sd: float
    rollouts_median: float
    reduction_pct: float | None
    reduction_ci: tuple[float, float] | None  # bootstrap 95% interval of reduction_pct
    median_reduction_pct: float | None
    p_value: float | None
    wall_mean_s: float
    wall_median_s: float
    wall_reduction_pct: float | None
    wall_p_value: float | None
    paper_reduction_pct: float | None
    kb_error_runs: int = 0
    baseline: str = BASELINE_METHOD
    targets: int = 1
    reduction_ci_targets: tuple[float, float] | None = None  # clustered: targets resampled
    beats: tuple[int, int] | None = None  # targets where its mean beat the baseline's, of all
    wall_cold_mean_s: float = 0.0  # the cold clock: predecessors and their fits included
    predecessor_rollouts_mean: float = 0.0  # beside `rollouts_mean`, never in it
    predecessor_s_mean: float = 0.0  # the predecessors' runs and the wait for their fits


def ordered(values: Iterable[str], preferred: Sequence[str]) -> list[str]:
    present = set(values)
    return [v for v in preferred if v in present] + sorted(present - set(preferred))


def _p_value(sample: np.ndarray, baseline: np.ndarray) -> float | None:
    """Two-sided Mann-Whitney U; None when either side is empty or all values tie."""
    if len(sample) == 0 or len(baseline) == 0:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        p = float(mannwhitneyu(sample, baseline, alternative="two-sided").pvalue)
    return None if math.isnan(p) else p


def _reduction(mean: float, baseline_mean: float | None) -> float | None:
    if baseline_mean is None or baseline_mean <= 0:
        return None
    return 100.0 * (baseline_mean - mean) / baseline_mean


BOOTSTRAP_RESAMPLES = 2000


def _reduction_ci(sample: np.ndarray, baseline: np.ndarray) -> tuple[float, float] | None:
    """A percentile bootstrap (both cells resampled, seeded) of the mean reduction: rollout
    counts are heavy-tailed, so the point estimate alone says little at n = 100."""
    if len(sample) < 2 or len(baseline) < 2:
        return None
    rng = np.random.default_rng(0)
    s = rng.choice(sample, (BOOTSTRAP_RESAMPLES, len(sample))).mean(axis=1)
    b = rng.choice(baseline, (BOOTSTRAP_RESAMPLES, len(baseline))).mean(axis=1)
    low, high = np.percentile(100.0 * (b - s) / b, [2.5, 97.5])
    return float(low), float(high)


def solved_at_budget(record: Mapping[str, Any]) -> bool:
    """Solved, and within the run's time budget if it had one (a rollout under way when the
    budget ran out may finish with the binding a little after it)."""
    budget = record.get("time_budget_s")
    return bool(record["solved"]) and (budget is None or float(record["wall_s"]) <= budget)


def time_metric(record: Mapping[str, Any]) -> float:
    """Seconds to the first binding; the time budget for a run unsolved within it."""
    budget = record.get("time_budget_s")
    if budget is None or solved_at_budget(record):
        return float(record["wall_s"])
    return float(budget)


def rollouts_metric(record: Mapping[str, Any]) -> float:
    """Rollouts to the first feasible binding; the cap for an unsolved run."""
    if record["solved"]:
        return float(record["rollouts"])
    return float(max(record["rollouts"], record.get("max_rollouts", record["rollouts"])))


def _by_target(
    runs: Sequence[Mapping[str, Any]], base: Sequence[Mapping[str, Any]]
) -> list[clustered.Target]:
    """The baseline's and the method's rollouts per target both ran (a record's `target`, set
    where a row pools targets, else its task)."""
    split: dict[str, tuple[list[float], list[float]]] = {}
    for arm, records in enumerate((base, runs)):
        for r in records:
            split.setdefault(str(r.get("target", r["task"])), ([], []))[arm].append(
                rollouts_metric(r)
            )
    return [(np.array(a), np.array(b)) for _, (a, b) in sorted(split.items()) if a and b]


def summarize(
    records: Iterable[Mapping[str, Any]],
    tasks: Sequence[str] = (),
    methods: Sequence[str] = (),
    baseline: str = BASELINE_METHOD,
) -> list[CellSummary]:
    """One row per (task, method) present in `records`, in the given order first, against
    `baseline` (the paper's figures beside only against the paper's baseline)."""
    cells: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in records:
        cells.setdefault((r["task"], r["method"]), []).append(r)
    rows = []
    for task in ordered((t for t, _ in cells), tasks):
        base = cells.get((task, baseline), [])
        base_roll = np.array([rollouts_metric(r) for r in base])
        base_wall = np.array([time_metric(r) for r in base])
        task_methods = (m for t, m in cells if t == task)
        for method in ordered(task_methods, methods):
            runs = cells[(task, method)]
            roll = np.array([rollouts_metric(r) for r in runs])
            wall = np.array([time_metric(r) for r in runs])
            vs_base = method != baseline and len(base) > 0
            targets = _by_target(runs, base) if vs_base else []
            pooled = len({r.get("target", r["task"]) for r in runs}) > 1
            rows.append(
                CellSummary(
                    task=task,
                    method=method,
                    n=len(runs),
                    solved_rate=float(np.mean([solved_at_budget(r) for r in runs])),
                    rollouts_mean=float(roll.mean()),
                    rollouts_sd=float(roll.std(ddof=1)) if len(roll) > 1 else 0.0,
                    rollouts_median=float(np.median(roll)),
                    reduction_pct=_reduction(roll.mean(), base_roll.mean()) if vs_base else None,
                    reduction_ci=_reduction_ci(roll, base_roll) if vs_base else None,
                    median_reduction_pct=_reduction(float(np.median(roll)), np.median(base_roll))
                    if vs_base
                    else None,
                    p_value=_p_value(roll, base_roll) if vs_base else None,
                    wall_mean_s=float(wall.mean()),
                    wall_median_s=float(np.median(wall)),
                    wall_reduction_pct=_reduction(wall.mean(), base_wall.mean())
                    if vs_base
                    else None,
                    wall_p_value=_p_value(wall, base_wall) if vs_base else None,
                    paper_reduction_pct=PAPER_REDUCTION_PERCENT.get(task)
                    if method in TRANSFER_METHODS and baseline == PAPER_BASELINE_METHOD
                    else None,
                    kb_error_runs=sum(1 for r in runs if r.get("kb_errors")),
                    baseline=baseline,
                    targets=len({r.get("target", r["task"]) for r in runs}),
                    reduction_ci_targets=clustered.reduction_ci(targets) if pooled else None,
                    beats=clustered.beats(targets) if pooled and targets else None,
                    wall_cold_mean_s=float(np.mean([clock_s(r, "cold") for r in runs])),
                    predecessor_rollouts_mean=float(
                        np.mean([predecessor_rollouts(r) for r in runs])
                    ),
                    predecessor_s_mean=float(
                        np.mean([clock_s(r, "cold") - clock_s(r, "warm") for r in runs])
                    ),
                )
            )
    return rows


def summarize_by_kind(
    records: Iterable[Mapping[str, Any]],
    kinds: Mapping[str, str],
    methods: Sequence[str] = (),
    baseline: str = BASELINE_METHOD,
) -> list[CellSummary]:
    """One row per (task kind, method), pooling every task of a kind (`kinds`: task -> kind),
    then per method a row of every kind (`all`): a generated suite is judged by kind, each
    kind's targets and seeds together, since one target's handful of seeds says little."""
    pooled = [
        {**r, "task": kinds[r["task"]], "target": r["task"]} for r in records if r["task"] in kinds
    ]
    everything = [{**r, "task": ALL_KINDS} for r in pooled]
    order = [*sorted(set(kinds.values())), ALL_KINDS]
    rows = summarize(pooled + everything, order, methods, baseline)
    # The paper's figures are for its own tasks, not for a kind of generated ones.
    return [dataclasses.replace(row, paper_reduction_pct=None) for row in rows]


def _fmt(value: float | None, spec: str, suffix: str = "") -> str:
    return "-" if value is None else f"{value:{spec}}{suffix}"


def _fmt_ci(ci: tuple[float, float] | None) -> str:
    return "-" if ci is None else f"[{ci[0]:.0f}%, {ci[1]:.0f}%]"


def _fmt_p(p: float | None) -> str:
    if p is None:
        return "-"
    return f"{p:.1e}" if p < 1e-3 else f"{p:.3f}"


def headers(baseline: str = BASELINE_METHOD) -> tuple[str, ...]:
    """The table's column names, the baseline named in them."""
    return (
        "task",
        "method",
        "n",
        "solved",
        "rollouts mean ± sd",
        "median",
        f"reduction vs {baseline}",
        "95% CI (runs)",
        "95% CI (targets)",
        "beats on",
        "median reduction",
        "paper",
        "p (MWU)",
        "predecessor rollouts",
        "wall warm mean",
        "wall median",
        "wall reduction",
        "wall p",
        "predecessor s",
        "wall cold mean",
        "KB errors",
    )


def table_rows(rows: Sequence[CellSummary]) -> list[list[str]]:
    """The summary as display strings, in `headers()` order."""
    return [
        [
            r.task,
            r.method,
            str(r.n),
            f"{100 * r.solved_rate:.0f}%",
            f"{r.rollouts_mean:.1f} ± {r.rollouts_sd:.1f}",
            f"{r.rollouts_median:g}",
            _fmt(r.reduction_pct, ".1f", "%"),
            _fmt_ci(r.reduction_ci),
            _fmt_ci(r.reduction_ci_targets),
            "-" if r.beats is None else f"{r.beats[0]}/{r.beats[1]}",
            _fmt(r.median_reduction_pct, ".1f", "%"),
            _fmt(r.paper_reduction_pct, ".2f", "%"),
            _fmt_p(r.p_value),
            f"{r.predecessor_rollouts_mean:.0f}" if r.predecessor_rollouts_mean else "-",
            f"{r.wall_mean_s:.2f} s",
            f"{r.wall_median_s:.2f} s",
            _fmt(r.wall_reduction_pct, ".1f", "%"),
            _fmt_p(r.wall_p_value),
            f"{r.predecessor_s_mean:.2f} s" if r.predecessor_s_mean else "-",
            f"{r.wall_cold_mean_s:.2f} s",
            f"{r.kb_error_runs} runs" if r.kb_error_runs else "-",
        ]
        for r in rows
    ]


def notes(baseline: str = BASELINE_METHOD) -> str:
    """What the table's counts include and what it is measured against."""
    against = (
        "the paper's baseline (one tree, never restarted), for the comparison with its figures"
        if baseline == PAPER_BASELINE_METHOD
        else "the strongest search without learning"
    )
    return (
        f"Reductions are against {baseline}, {against}. 95% CI (runs): runs resampled; "
        "95% CI (targets): targets resampled, then seeds within (rows pooling targets); "
        f"beats on: targets where the mean is below {baseline}'s. {COUNTS_NOTE}"
    )


def markdown_table(rows: Sequence[CellSummary], baseline: str = BASELINE_METHOD) -> str:
    names = headers(baseline)
    lines = ["| " + " | ".join(names) + " |", "|" + "---|" * len(names)]
    lines += ["| " + " | ".join(cells) + " |" for cells in table_rows(rows)]
    return "\n".join(lines) + "\n\n" + notes(baseline) + "\n"


def write_summary(
    rows: Sequence[CellSummary],
    out_dir: Path | str,
    name: str = "summary",
    baseline: str = BASELINE_METHOD,
) -> list[Path]:
    """`summary.md` (the table and its notes) and `summary.csv` (full precision)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = out / f"{name}.md"
    md.write_text(markdown_table(rows, baseline), encoding="utf-8")
    path_csv = out / f"{name}.csv"
    fields = list(CellSummary.__dataclass_fields__)
    with path_csv.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for r in rows:
            writer.writerow(asdict(r))
    return [md, path_csv]

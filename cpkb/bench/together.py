"""The summary of a `--concurrent N` bench against the same seeds run alone.

Runs are paired by (task, method, seed): the same seed alone on its own fresh knowledge base
and with N - 1 others on a shared one. Rollouts are the measure (N planners share the cores,
so their wall time is not comparable); wall time and the knowledge-base time by part are
reported beside it, and the groups' point counts say whether a point was lost or stored twice.
"""

from __future__ import annotations

import csv
import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import wilcoxon

from cpkb.bench.stats import BOOTSTRAP_RESAMPLES, ordered, rollouts_metric

ALL_TASKS = "all"
KB_PARTS = ("match", "suggest", "fetch", "post", "fit", "close")


@dataclass(frozen=True)
class TogetherRow:
    """One (task, method) cell: its runs together against the same seeds alone."""

    task: str
    method: str
    concurrent: int
    mixed: bool
    n: int  # seeds with a run in both arms
    alone_mean: float
    together_mean: float
    ratio: float | None  # together / alone, of the mean rollouts
    ratio_ci: tuple[float, float] | None  # paired bootstrap 95% interval
    p_value: float | None  # Wilcoxon signed-rank on the pairs
    alone_median: float
    together_median: float
    alone_wall_s: float
    together_wall_s: float
    alone_kb_s: float
    together_kb_s: float
    together_kb_parts: dict[str, float] = field(default_factory=dict)  # mean s per run
    live_points: float = 0.0  # mean other planners' points a run took in
    kb_error_runs: int = 0


def _mean(values: Iterable[float]) -> float:
    array = np.asarray(list(values), dtype=float)
    return float(array.mean()) if array.size else math.nan


def ratio_ci(alone: np.ndarray, together: np.ndarray) -> tuple[float, float] | None:
    """The bootstrap 95 % interval of mean(`together`) / mean(`alone`): pairs resampled
    together (seeded), the ratio of the means each time."""
    if len(alone) < 2:
        return None
    rng = np.random.default_rng(0)
    picks = rng.integers(0, len(alone), (BOOTSTRAP_RESAMPLES, len(alone)))
    base = alone[picks].mean(axis=1)
    ratios = together[picks].mean(axis=1) / np.where(base > 0, base, np.nan)
    low, high = np.nanpercentile(ratios, [2.5, 97.5])
    return float(low), float(high)


def _p_value(alone: np.ndarray, together: np.ndarray) -> float | None:
    if len(alone) < 2 or np.all(alone == together):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        p = float(wilcoxon(together, alone).pvalue)
    return None if math.isnan(p) else p


def _row(
    task: str, method: str, pairs: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]]
) -> TogetherRow:
    alone = np.array([rollouts_metric(a) for a, _ in pairs])
    together = np.array([rollouts_metric(t) for _, t in pairs])
    runs = [t for _, t in pairs]
    parts = {
        part: _mean(float(r.get("kb_parts", {}).get(part, 0.0)) for r in runs)
        for part in ordered({p for r in runs for p in r.get("kb_parts", {})}, KB_PARTS)
    }
    alone_mean = float(alone.mean())
    return TogetherRow(
        task=task,
        method=method,
        concurrent=max(int(r.get("concurrent", 1)) for r in runs),
        mixed=any(bool(r.get("mixed")) for r in runs),
        n=len(pairs),
        alone_mean=alone_mean,
        together_mean=float(together.mean()),
        ratio=float(together.mean()) / alone_mean if alone_mean > 0 else None,
        ratio_ci=ratio_ci(alone, together),
        p_value=_p_value(alone, together),
        alone_median=float(np.median(alone)),
        together_median=float(np.median(together)),
        alone_wall_s=_mean(float(a["wall_s"]) for a, _ in pairs),
        together_wall_s=_mean(float(r["wall_s"]) for r in runs),
        alone_kb_s=_mean(float(a.get("kb_s") or 0.0) for a, _ in pairs),
        together_kb_s=_mean(float(r.get("kb_s") or 0.0) for r in runs),
        together_kb_parts=parts,
        live_points=_mean(float(r.get("live_points") or 0) for r in runs),
        kb_error_runs=sum(1 for r in runs if r.get("kb_errors")),
    )


def summarize_together(
    together: Iterable[Mapping[str, Any]],
    alone: Iterable[Mapping[str, Any]],
    tasks: Sequence[str] = (),
    methods: Sequence[str] = (),
) -> list[TogetherRow]:
    """One row per (task, method) with runs in both arms, then one per method over every task."""
    by_key = {(r["task"], r["method"], int(r["seed"])): r for r in alone}
    cells: dict[tuple[str, str], list[tuple[Mapping[str, Any], Mapping[str, Any]]]] = {}
    for record in together:
        partner = by_key.get((record["task"], record["method"], int(record["seed"])))
        if partner is not None:
            cells.setdefault((record["task"], record["method"]), []).append((partner, record))
    rows = []
    for method in ordered({m for _, m in cells}, methods):
        present = [t for t, m in cells if m == method]
        for task in ordered(present, tasks):
            rows.append(_row(task, method, cells[(task, method)]))
        if len(present) > 1:
            rows.append(_row(ALL_TASKS, method, [p for t in present for p in cells[(t, method)]]))
    return rows


@dataclass(frozen=True)
class GroupCheck:
    """Whether the groups' bases hold exactly the points their runs posted."""

    groups: int
    points_posted: int
    points_stored: int
    mismatched: list[str]  # groups whose counts differ (or could not be read)

    @classmethod
    def of(cls, groups: Iterable[Mapping[str, Any]]) -> GroupCheck:
        groups = list(groups)
        return cls(
            groups=len(groups),
            points_posted=sum(int(g["points_posted"]) for g in groups),
            points_stored=sum(int(g["points_stored"] or 0) for g in groups),
            mismatched=[g["group"] for g in groups if g["points_stored"] != g["points_posted"]],
        )

    def line(self) -> str:
        verdict = (
            "none lost or doubled"
            if not self.mismatched
            else (f"MISMATCH in {len(self.mismatched)} groups: {', '.join(self.mismatched[:5])}")
        )
        return (
            f"{self.groups} groups: {self.points_posted} points posted, "
            f"{self.points_stored} stored ({verdict})"
        )


HEADERS = (
    "task",
    "method",
    "N",
    "pairs",
    "alone mean",
    "together mean",
    "together / alone",
    "95% CI",
    "p (Wilcoxon)",
    "alone median",
    "together median",
    "wall alone",
    "wall together",
    "KB alone",
    "KB together",
    "KB together by part",
    "live points",
    "KB errors",
)


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None or math.isnan(value) else f"{value:{spec}}"


def table_rows(rows: Sequence[TogetherRow]) -> list[list[str]]:
    return [
        [
            r.task,
            r.method,
            f"{r.concurrent}{' mixed' if r.mixed else ''}",
            str(r.n),
            f"{r.alone_mean:.1f}",
            f"{r.together_mean:.1f}",
            _fmt(r.ratio, ".2f"),
            "-" if r.ratio_ci is None else f"[{r.ratio_ci[0]:.2f}, {r.ratio_ci[1]:.2f}]",
            "-" if r.p_value is None else f"{r.p_value:.3f}",
            f"{r.alone_median:g}",
            f"{r.together_median:g}",
            f"{r.alone_wall_s:.2f} s",
            f"{r.together_wall_s:.2f} s",
            f"{r.alone_kb_s:.2f} s",
            f"{r.together_kb_s:.2f} s",
            " ".join(f"{part} {s:.2f}" for part, s in r.together_kb_parts.items()) or "-",
            f"{r.live_points:.0f}",
            f"{r.kb_error_runs} runs" if r.kb_error_runs else "-",
        ]
        for r in rows
    ]


def write_together(
    rows: Sequence[TogetherRow], check: GroupCheck, out_dir: Path | str
) -> list[Path]:
    """`summary_concurrent.md` (the table and the point check) and `.csv` (full precision)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["| " + " | ".join(HEADERS) + " |", "|" + "---|" * len(HEADERS)]
    lines += ["| " + " | ".join(cells) + " |" for cells in table_rows(rows)]
    md = out / "summary_concurrent.md"
    md.write_text("\n".join([*lines, "", check.line()]) + "\n", encoding="utf-8")
    path_csv = out / "summary_concurrent.csv"
    with path_csv.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(TogetherRow.__dataclass_fields__))
        writer.writeheader()
        for r in rows:
            writer.writerow(asdict(r))
    return [md, path_csv]

"""Box plots in the manner of the paper's Fig. 5: one panel per task, one box per method."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # headless: benches run on servers and in CI

import matplotlib.pyplot as plt

from cpkb.bench.stats import ordered, rollouts_metric


def box_plot(
    records: Iterable[Mapping[str, Any]],
    metric: Callable[[Mapping[str, Any]], float],
    path: Path | str,
    *,
    ylabel: str,
    title: str,
    tasks: Sequence[str] = (),
    methods: Sequence[str] = (),
    log: bool = True,
) -> Path:
    """Write a PNG of `metric` per method, one panel per task; the mean is marked with a dot."""
    data: dict[str, dict[str, list[float]]] = {}
    for r in records:
        data.setdefault(r["task"], {}).setdefault(r["method"], []).append(metric(r))
    task_order = ordered(data, tasks) or ["(no runs)"]
    fig, axes = plt.subplots(
        1, len(task_order), figsize=(max(6.0, 4.4 * len(task_order)), 5.0), squeeze=False
    )
    for ax, task in zip(axes[0], task_order, strict=True):
        cell = data.get(task, {})
        names = ordered(cell, methods)
        if names:
            ax.boxplot(
                [cell[m] for m in names],
                showmeans=True,
                meanprops={"marker": "o", "markerfacecolor": "white", "markeredgecolor": "black"},
            )
            ax.set_xticks(range(1, len(names) + 1))
            ax.set_xticklabels(
                [f"{m}\n(n={len(cell[m])})" for m in names], rotation=30, ha="right", fontsize=8
            )
        if log:
            ax.set_yscale("log")
        ax.set_title(task)
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].set_ylabel(ylabel)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def write_plots(
    records: Sequence[Mapping[str, Any]],
    out_dir: Path | str,
    tasks: Sequence[str] = (),
    methods: Sequence[str] = (),
) -> list[Path]:
    """`rollouts.png` (the paper's metric) and `wall_time.png` (time to the first binding)."""
    out = Path(out_dir)
    return [
        box_plot(
            records,
            rollouts_metric,
            out / "rollouts.png",
            ylabel="rollouts to the first feasible binding",
            title="Rollouts per method (log scale; box: quartiles, o: mean; unsolved = cap)",
            tasks=tasks,
            methods=methods,
        ),
        box_plot(
            records,
            lambda r: float(r["wall_s"]),
            out / "wall_time.png",
            ylabel="wall time to the first feasible binding, s",
            title="Wall time per method (log scale; target task only)",
            tasks=tasks,
            methods=methods,
        ),
    ]

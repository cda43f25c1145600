"""Box plots in the manner of the paper's Fig. 5: one panel per task, one box per method, with
the mean and the median each beside a 95% bootstrap interval, since rollout counts are
heavy-tailed and a box alone hides how sure its centre is.

Each figure is written as PNG (for a quick look) and as SVG and PDF (vector, for papers)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # headless: benches run on servers and in CI

import matplotlib.pyplot as plt
import numpy as np
from matplotlib import ticker
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.typing import RcKeyType

from cpkb.bench.scenarios import task_kinds
from cpkb.bench.stats import BOOTSTRAP_RESAMPLES, ordered, rollouts_metric, time_metric

# Okabe and Ito's palette: told apart with every common form of colour blindness and in grey.
PALETTE = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000")
PNG_DPI = 200
FORMATS = ("png", "svg", "pdf")
STYLE: dict[RcKeyType, Any] = {
    "font.family": "DejaVu Sans",  # shipped with matplotlib: the same glyphs on every machine
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "pdf.fonttype": 42,  # TrueType in the PDF: editable text, accepted by publishers
    "svg.fonttype": "path",  # the SVG looks the same without the font installed
    "svg.hashsalt": "cpkb",  # the same runs give the same SVG
}
# Offsets of the interval marks from a box's centre, in box positions.
MEAN_OFFSET = 0.34
MEDIAN_OFFSET = -0.34
MAX_COLUMNS = 5  # panels per row: a 30-task suite still fits a page


def bootstrap_ci(
    values: Sequence[float], statistic: Callable[[np.ndarray], np.ndarray]
) -> tuple[float, float] | None:
    """A seeded percentile bootstrap 95% interval of `statistic` (applied along axis 1 of the
    resamples); None below two values, where a resample says nothing."""
    sample = np.asarray(values, dtype=float)
    if len(sample) < 2:
        return None
    rng = np.random.default_rng(0)
    stats = statistic(rng.choice(sample, (BOOTSTRAP_RESAMPLES, len(sample))))
    low, high = np.percentile(stats, [2.5, 97.5])
    return float(low), float(high)


def _mean(resamples: np.ndarray) -> np.ndarray:
    return resamples.mean(axis=1)


def _median(resamples: np.ndarray) -> np.ndarray:
    return np.median(resamples, axis=1)


def _log_axis(ax: Axes) -> None:
    """Labels at 1, 2 and 5 of each decade as plain numbers: a reader sees 20 or 500 rollouts
    without decoding 10^x, and a narrow range still gets several labels."""
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_minor_locator(ticker.LogLocator(base=10, subs=tuple(range(1, 10)), numticks=100))
    ax.yaxis.set_major_formatter(ticker.FuncFormatter(lambda y, _: f"{y:g}"))
    ax.yaxis.set_minor_formatter(ticker.NullFormatter())


def _interval(
    ax: Axes, x: float, centre: float, ci: tuple[float, float] | None, **style: Any
) -> None:
    low, high = ci if ci is not None else (centre, centre)
    ax.errorbar(
        [x],
        [centre],
        yerr=[[centre - low], [high - centre]],
        capsize=3,
        elinewidth=1.1,
        ecolor="black",
        linestyle="none",
        zorder=4,
        **style,
    )


def _panel(
    ax: Axes, cell: Mapping[str, list[float]], names: Sequence[str], colours: Mapping[str, str]
) -> None:
    series = [cell[m] for m in names]
    parts = ax.boxplot(
        series,
        widths=0.42,
        patch_artist=True,
        medianprops={"color": "black", "linewidth": 1.6},
        whiskerprops={"color": "0.25"},
        capprops={"color": "0.25"},
        flierprops={
            "marker": "x",
            "markersize": 4,
            "markeredgecolor": "0.35",
            "markeredgewidth": 0.8,
            "linestyle": "none",
        },
    )
    for box, name in zip(parts["boxes"], names, strict=True):
        box.set(facecolor=colours[name], alpha=0.45, edgecolor="0.2")
    for i, (name, values) in enumerate(zip(names, series, strict=True), start=1):
        _interval(
            ax,
            i + MEAN_OFFSET,
            float(np.mean(values)),
            bootstrap_ci(values, _mean),
            marker="D",
            markersize=5,
            markerfacecolor=colours[name],
            markeredgecolor="black",
        )
        _interval(
            ax,
            i + MEDIAN_OFFSET,
            float(np.median(values)),
            bootstrap_ci(values, _median),
            marker="_",
            markersize=9,
            markeredgewidth=1.6,
            color="black",
        )
    ax.set_xticks(range(1, len(names) + 1))
    ax.set_xticklabels([f"{m}\n(n={len(cell[m])})" for m in names], rotation=30, ha="right")
    ax.set_xlim(0.4, len(names) + 0.6)


LEGEND = [
    Patch(facecolor="0.8", edgecolor="0.2", label="quartiles, whiskers 1.5 IQR"),
    Line2D([], [], color="black", linewidth=1.6, label="median; its 95% CI at left"),
    Line2D(
        [],
        [],
        marker="D",
        markersize=5,
        markerfacecolor="white",
        markeredgecolor="black",
        linestyle="none",
        label="mean; its 95% CI at right",
    ),
    Line2D([], [], marker="x", markersize=4, color="0.35", linestyle="none", label="outlying run"),
]


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
) -> list[Path]:
    """Write `metric` per method, one panel per task, as `path` with each of FORMATS' suffixes;
    a method keeps its colour in every panel."""
    data: dict[str, dict[str, list[float]]] = {}
    for r in records:
        data.setdefault(r["task"], {}).setdefault(r["method"], []).append(metric(r))
    task_order = ordered(data, tasks) or ["(no runs)"]
    every_method = ordered({m for cell in data.values() for m in cell}, methods)
    colours = {m: PALETTE[i % len(PALETTE)] for i, m in enumerate(every_method)}
    with plt.rc_context(STYLE):
        cols = min(len(task_order), MAX_COLUMNS)
        rows = -(-len(task_order) // cols)
        fig, axes = plt.subplots(
            rows, cols, figsize=(max(6.4, 3.6 * cols), 0.6 + 4.0 * rows), squeeze=False
        )
        for ax in axes.flat[len(task_order) :]:
            ax.set_visible(False)
        for ax, task in zip(axes.flat, task_order, strict=False):
            cell = data.get(task, {})
            names = ordered(cell, methods)
            if names:
                _panel(ax, cell, names, colours)
            if log:
                _log_axis(ax)
            ax.set_title(_short(task))
            ax.grid(axis="y", which="major", alpha=0.35)
            ax.grid(axis="y", which="minor", alpha=0.12)
        for row in axes:
            row[0].set_ylabel(ylabel)
        fig.suptitle(title)
        fig.legend(handles=LEGEND, loc="lower center", ncol=len(LEGEND), frameon=False)
        height = fig.get_figheight()
        fig.tight_layout(rect=(0, 0.3 / height, 1, 1 - 0.3 / height))
        stem = Path(path).with_suffix("")
        stem.parent.mkdir(parents=True, exist_ok=True)
        written = []
        for fmt in FORMATS:
            out = stem.with_suffix(f".{fmt}")
            fig.savefig(out, dpi=PNG_DPI, metadata=_metadata(fmt))
            written.append(out)
        plt.close(fig)
    return written


def _short(task: str) -> str:
    """A generated task by its workspace and file (`ws03/desk.yaml`): the suite's directory is
    the same in every panel and would crowd the title out."""
    path = Path(task)
    return f"{path.parent.name}/{path.name}" if len(path.parts) > 2 else task


def _metadata(fmt: str) -> dict[str, Any]:
    """No creation date in vector files, so a rebuilt report only differs where runs do."""
    return {"Date": None} if fmt in ("svg", "pdf") else {}


def shared_kinds(records: Sequence[Mapping[str, Any]]) -> dict[str, str]:
    """Task -> kind when some kind has several tasks (a generated suite), as `summary_by_kind`
    is written; empty otherwise."""
    kinds = task_kinds({r["task"] for r in records})
    return kinds if len(kinds) > len(set(kinds.values())) else {}


def write_plots(
    records: Sequence[Mapping[str, Any]],
    out_dir: Path | str,
    tasks: Sequence[str] = (),
    methods: Sequence[str] = (),
) -> list[Path]:
    """`rollouts.*` (the paper's metric), `wall_time.*` (time to the first binding) and, for a
    suite whose tasks share kinds, `rollouts_by_kind.*` pooling each kind's tasks."""
    out = Path(out_dir)
    paths = box_plot(
        records,
        rollouts_metric,
        out / "rollouts",
        ylabel="rollouts to the first feasible binding",
        title="Rollouts per method (log scale; an unsolved run counts as the cap)",
        tasks=tasks,
        methods=methods,
    )
    paths += box_plot(
        records,
        time_metric,
        out / "wall_time",
        ylabel="wall time to the first feasible binding, s",
        title="Wall time per method (log scale; target task only)",
        tasks=tasks,
        methods=methods,
    )
    kinds = shared_kinds(records)
    if kinds:
        pooled = [{**r, "task": kinds[r["task"]]} for r in records if r["task"] in kinds]
        paths += box_plot(
            pooled,
            rollouts_metric,
            out / "rollouts_by_kind",
            ylabel="rollouts to the first feasible binding",
            title="Rollouts per method and task kind, targets and seeds pooled (log scale)",
            tasks=sorted(set(kinds.values())),
            methods=methods,
        )
    return paths

"""The summary table and the plots, from hand-made result records and from a slice of a real
bench kept compressed, as the repository keeps its runs."""

from __future__ import annotations

import shutil
import statistics
from pathlib import Path

import pytest
from scipy.stats import mannwhitneyu

from cpkb.bench.app import BenchSettings, run_command
from cpkb.bench.plots import write_plots
from cpkb.bench.results import ResultStore
from cpkb.bench.scenarios import PAPER_BASELINE_METHOD, expand
from cpkb.bench.stats import markdown_table, summarize, write_summary

# Desk, quasi-random and cp-bo-transfer, seeds 100-119 of `benchmarks/results/paper9`.
PAPER9_DESK = Path(__file__).parent / "fixtures" / "paper9-desk"
PAPER9_METHODS = ["quasi-random", "cp-bo-transfer"]


def _records(task: str, method: str, rollouts: list[int], solved_cap: int = 2000) -> list[dict]:
    return [
        {
            "task": task,
            "method": method,
            "seed": i,
            "rollouts": r,
            "solved": r < solved_cap,
            "wall_s": r / 100,
        }
        for i, r in enumerate(rollouts)
    ]


QR = [10, 20, 30, 40, 2000]
TRANSFER = [1, 2, 3, 4, 5]


def test_cells_give_mean_sd_median_solved_reduction_and_p_value() -> None:
    records = _records("desk", "quasi-random", QR) + _records("desk", "cp-bo-transfer", TRANSFER)
    rows = summarize(records, ["desk"], ["quasi-random", "cp-bo-transfer"], PAPER_BASELINE_METHOD)
    assert [(r.task, r.method) for r in rows] == [
        ("desk", "quasi-random"),
        ("desk", "cp-bo-transfer"),
    ]
    qr, tr = rows
    assert qr.n == 5 and qr.solved_rate == pytest.approx(0.8)
    assert qr.rollouts_mean == pytest.approx(420.0) and qr.rollouts_median == 30
    assert qr.rollouts_sd == pytest.approx(statistics.stdev(QR))
    assert qr.reduction_pct is None and qr.p_value is None and qr.paper_reduction_pct is None
    assert tr.reduction_pct == pytest.approx(100 * (420 - 3) / 420)
    assert tr.wall_reduction_pct == pytest.approx(tr.reduction_pct)
    assert tr.p_value == pytest.approx(mannwhitneyu(TRANSFER, QR).pvalue)
    assert tr.paper_reduction_pct == 71.69
    assert tr.median_reduction_pct == pytest.approx(100 * (30 - 3) / 30)
    # The quasi-random mean rests on one 2000-rollout run: resamples without it reduce far less.
    low, high = tr.reduction_ci
    assert 0 < low < 90 < tr.reduction_pct <= high < 100
    assert qr.reduction_ci is None and qr.median_reduction_pct is None
    table = markdown_table(rows, PAPER_BASELINE_METHOD)
    assert "| reduction vs quasi-random |" in table and "the paper's baseline" in table
    assert "| desk | cp-bo-transfer | 5 | 100% | 3.0 ± 1.6 | 3 | 99.3% | [" in table
    assert "| 90.0% | 71.69% |" in table


def test_cells_without_a_baseline_have_no_reduction_and_unknown_cells_come_last() -> None:
    records = _records("pack", "cp-bo", [3, 3, 3]) + _records("desk", "mcts-bo", [5, 6])
    rows = summarize(records, ["desk"], ["mcts-bo", "cp-bo"])
    assert [(r.task, r.method) for r in rows] == [("desk", "mcts-bo"), ("pack", "cp-bo")]
    assert all(r.reduction_pct is None and r.p_value is None for r in rows)


def test_writes_table_files_and_plots(tmp_path: Path) -> None:
    records = (
        _records("desk", "quasi-random", QR)
        + _records("desk", "cp-bo", [5, 8, 13])
        + _records("pack", "quasi-random", [30, 50])
    )
    rows = summarize(records)
    paths = write_summary(rows, tmp_path) + write_plots(records, tmp_path, ["desk", "pack"])
    assert [p.name for p in paths] == [
        "summary.md",
        "summary.csv",
        *(f"{stem}.{fmt}" for stem in ("rollouts", "wall_time") for fmt in ("png", "svg", "pdf")),
    ]
    assert (tmp_path / "summary.csv").read_text().startswith("task,method,n,solved_rate,")
    for png in (tmp_path / "rollouts.png", tmp_path / "wall_time.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


def test_compressed_runs_are_read_as_finished_runs() -> None:
    store = ResultStore(PAPER9_DESK)
    assert not store.runs_path.exists()
    records = store.records()
    assert len(records) == 40
    assert store.pending(expand(["desk"], PAPER9_METHODS, range(100, 120))) == []
    rows = summarize(records, ["desk"], PAPER9_METHODS, PAPER_BASELINE_METHOD)
    qr, tr = (
        [r["rollouts"] for r in records if r["method"] == method] for method in PAPER9_METHODS
    )
    assert rows[0].rollouts_mean == pytest.approx(statistics.mean(qr))
    assert rows[1].rollouts_median == statistics.median(tr)
    assert rows[1].p_value == pytest.approx(mannwhitneyu(tr, qr).pvalue)
    assert 0 < rows[1].reduction_ci[0] < rows[1].reduction_pct < rows[1].reduction_ci[1]


def test_summary_only_rebuilds_the_table_from_compressed_runs(tmp_path: Path) -> None:
    out = tmp_path / "paper9-desk"
    shutil.copytree(PAPER9_DESK, out)
    settings = BenchSettings(
        tasks=["desk"],
        methods=PAPER9_METHODS,
        seeds=range(100, 120),
        workers=1,
        out_dir=out,
        summary_only=True,
        quiet=True,
    )
    assert run_command(settings) == 0
    table = (out / "summary.md").read_text()
    assert "| desk | quasi-random | 20 | 100% |" in table
    assert "| desk | cp-bo-transfer | 20 | 100% |" in table
    assert (out / "rollouts.png").stat().st_size > 5000
    assert not (out / "runs.jsonl").exists()


def test_a_suite_is_summarised_by_kind_pooling_its_targets() -> None:
    from cpkb.bench.stats import summarize_by_kind

    records = (
        _records("a/desk.yaml", "quasi-random", [10, 30])
        + _records("b/desk.yaml", "quasi-random", [50, 70])
        + _records("a/desk.yaml", "cp-bo-transfer", [1, 3])
        + _records("b/desk.yaml", "cp-bo-transfer", [5, 7])
        + _records("a/pack.yaml", "quasi-random", [8, 8])
    )
    kinds = {"a/desk.yaml": "desk", "b/desk.yaml": "desk", "a/pack.yaml": "pack"}
    rows = {
        (r.task, r.method): r
        for r in summarize_by_kind(records, kinds, baseline=PAPER_BASELINE_METHOD)
    }
    transfer = rows[("desk", "cp-bo-transfer")]
    assert transfer.n == 4 and rows[("desk", "quasi-random")].n == 4
    assert transfer.reduction_pct == pytest.approx(100 * (40 - 4) / 40)
    assert transfer.paper_reduction_pct is None
    assert rows[("pack", "quasi-random")].rollouts_mean == pytest.approx(8)
    assert transfer.targets == 2 and transfer.beats == (2, 2)
    assert transfer.reduction_ci_targets is not None
    everything = rows[("all", "quasi-random")]
    assert everything.n == 6 and everything.targets == 3
    every_base = (10 + 30 + 50 + 70 + 8 + 8) / 6  # pack's too: a row pools its cells' runs
    assert rows[("all", "cp-bo-transfer")].reduction_pct == pytest.approx(
        100 * (every_base - 4) / every_base
    )


def test_every_summary_is_against_the_strongest_baseline_unless_told() -> None:
    records = (
        _records("desk", "quasi-random", QR)
        + _records("desk", "quasi-random-restarts", [10, 20, 30, 40, 50])
        + _records("desk", "cp-bo-transfer", TRANSFER)
    )
    strongest = {r.method: r for r in summarize(records)}
    transfer = strongest["cp-bo-transfer"]
    assert transfer.baseline == "quasi-random-restarts"
    assert transfer.reduction_pct == pytest.approx(100 * (30 - 3) / 30)
    assert transfer.paper_reduction_pct is None  # the paper's figure is against its baseline
    assert strongest["quasi-random"].reduction_pct == pytest.approx(100 * (30 - 420) / 30)
    assert "| reduction vs quasi-random-restarts |" in markdown_table(list(strongest.values()))
    paper = {r.method: r for r in summarize(records, baseline=PAPER_BASELINE_METHOD)}
    assert paper["cp-bo-transfer"].reduction_pct == pytest.approx(100 * (420 - 3) / 420)
    assert paper["cp-bo-transfer"].paper_reduction_pct == 71.69


def test_generated_targets_are_known_by_their_declared_kind() -> None:
    from cpkb.bench.scenarios import task_kinds

    suite = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "dev"
    targets = sorted(str(p) for p in suite.glob("ws0*/desk.yaml"))[:2]
    kinds = task_kinds([*targets, "analytic:desk", "no-such-task"])
    assert kinds == dict.fromkeys(targets, "desk")

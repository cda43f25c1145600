"""The two clocks of a run: warm (the target alone, its knowledge base stocked and fitted
before) and cold (the predecessors, the wait for their fits and the target), recorded with
every run and shown by the summaries beside the predecessors' rollouts."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import pytest
from bench_toy_planner import toy_run

from cpkb.bench.clocks import COUNTS_NOTE, clock_s, predecessor_rollouts
from cpkb.bench.results import ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import expand
from cpkb.bench.stats import markdown_table, summarize

FIT_WAIT_S = 2.5


@dataclass(frozen=True)
class FittedKbs:
    """A knowledge-base service whose fits took `FIT_WAIT_S` to land (as reported)."""

    url: str = "http://127.0.0.1:9"

    def create(self, name: str) -> None:
        pass

    def delete(self, name: str) -> None:
        pass

    def delete_prefix(self, prefix: str) -> int:
        return 0

    def wait_fitted(self, name: str) -> float:
        return FIT_WAIT_S

    def count_points(self, name: str) -> int:
        return 0


def test_the_cold_clock_adds_the_predecessors_and_their_fits_to_the_warm_one():
    record = {
        "wall_s": 2.0,
        "predecessor_wall_s": 3.0,
        "fit_wait_s": 4.0,
        "predecessors": [{"rollouts": 1, "rollouts_spent": 30}, {"rollouts": 30}],
    }
    assert clock_s(record, "warm") == 2.0
    assert clock_s(record, "cold") == 9.0
    assert predecessor_rollouts(record) == 60
    alone = {"wall_s": 2.0}  # a method without predecessors reads alike on both
    assert clock_s(alone, "cold") == clock_s(alone, "warm") == 2.0
    assert predecessor_rollouts(alone) == 0


def test_a_bench_records_both_clocks_and_the_predecessors_rollouts(tmp_path: Path):
    run = functools.partial(toy_run, log_path=str(tmp_path / "calls.jsonl"))
    scenarios = expand(["regrasp"], ["cp-bo", "cp-bo-transfer"], range(2))
    outcome = run_bench(
        scenarios,
        tmp_path / "out",
        run,
        workers=1,
        max_rollouts=300,
        predecessor_rollouts=30,
        predecessor_kwargs={"stop_at_first": False},
        kb_service=FittedKbs(),
    )
    assert outcome.finished == 4
    records = ResultStore(tmp_path / "out").records()
    for r in records:
        assert r["clock_warm_s"] == r["wall_s"]
        transfer = r["method"] == "cp-bo-transfer"
        waited = FIT_WAIT_S if transfer else 0.0
        assert r["fit_wait_s"] == waited
        assert r["clock_cold_s"] == pytest.approx(r["predecessor_wall_s"] + waited + r["wall_s"])
        # regrasp's predecessors, deskP and desk, spend their whole 30 rollouts each
        assert r["predecessor_rollouts"] == (60 if transfer else 0)
    rows = {row.method: row for row in summarize(records)}
    transfer = rows["cp-bo-transfer"]
    assert transfer.predecessor_rollouts_mean == 60
    assert transfer.wall_cold_mean_s == pytest.approx(
        transfer.wall_mean_s + transfer.predecessor_s_mean
    )
    assert transfer.predecessor_s_mean >= FIT_WAIT_S
    assert rows["cp-bo"].wall_cold_mean_s == pytest.approx(rows["cp-bo"].wall_mean_s)
    table = markdown_table(list(rows.values()))
    assert "| predecessor rollouts |" in table and "| wall cold mean |" in table
    assert COUNTS_NOTE in table

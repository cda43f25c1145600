"""Each scenario gets a fresh knowledge base on a real (embedded) service, deleted after it."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest
from bench_toy_planner import toy_run_with_kb

from client import CpkbClient
from cpkb.bench.app import knowledge_service
from cpkb.bench.results import ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import expand


@pytest.mark.slow
def test_fresh_knowledge_base_per_scenario_shared_by_its_predecessors(tmp_path: Path) -> None:
    run = functools.partial(toy_run_with_kb, log_path=str(tmp_path / "calls.jsonl"))
    scenarios = expand(["desk", "pack"], ["cp-bo", "cp-bo-transfer"], range(2))
    with knowledge_service(None, None) as kbs:
        outcome = run_bench(
            scenarios, tmp_path / "out", run, workers=2, max_rollouts=100, kb_service=kbs
        )
        with CpkbClient(kbs.url) as client:
            left = [kb.name for kb in client.list_kbs()]
    assert (outcome.finished, outcome.errors) == (8, 0)
    assert left == ["default"]
    by_cell = {(r["task"], r["method"]): r for r in ResultStore(tmp_path / "out").records()}
    # cp-bo starts empty; transfer's target sees one point per predecessor, and no other run's.
    assert by_cell[("desk", "cp-bo")]["kb_points_before"] == 0
    assert by_cell[("desk", "cp-bo-transfer")]["kb_points_before"] == 1
    assert by_cell[("pack", "cp-bo-transfer")]["kb_points_before"] == 3


@pytest.mark.slow
def test_runs_cut_short_leave_no_knowledge_base_behind(tmp_path: Path) -> None:
    """The runs outlast the limit, which is long enough for them to have stocked their
    knowledge bases (the log shows it) on a loaded machine too."""
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run_with_kb, log_path=str(log), sleep_s=600.0)
    with knowledge_service(None, None) as kbs:
        outcome = run_bench(
            expand(["desk"], ["cp-bo"], range(4)),
            tmp_path / "out",
            run,
            workers=2,
            max_rollouts=100,
            kb_service=kbs,
            time_limit_s=30,
        )
        with CpkbClient(kbs.url) as client:
            left = [kb.name for kb in client.list_kbs()]
    assert outcome.timed_out and outcome.finished == 0
    assert log.read_text().splitlines()  # runs in flight had posted to their KBs
    assert left == ["default"]

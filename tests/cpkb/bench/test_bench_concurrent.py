"""`run_bench(concurrent=N)`: a cell's runs N at a time on one knowledge base of a real service."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest
from bench_toy_planner import toy_run_with_kb

from client import CpkbClient
from cpkb.bench.app import knowledge_service
from cpkb.bench.kbs import ServiceKbs
from cpkb.bench.results import BenchConfigError, ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import expand


@pytest.mark.slow
def test_groups_of_n_seeds_share_one_knowledge_base_and_start_together(tmp_path: Path) -> None:
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run_with_kb, log_path=str(log))
    scenarios = expand(["desk", "pack"], ["cp-bo"], range(10, 15))
    with knowledge_service(None, None) as kbs:
        outcome = run_bench(
            scenarios,
            tmp_path / "out",
            run,
            workers=1,
            max_rollouts=100,
            kb_service=kbs,
            concurrent=2,
        )
        with CpkbClient(kbs.url) as client:
            left = [kb.name for kb in client.list_kbs()]
    assert (outcome.finished, outcome.errors) == (10, 0)
    assert left == ["default"]
    records = {(r["task"], r["seed"]): r for r in ResultStore(tmp_path / "out").records()}
    for task in ("desk", "pack"):
        groups = [records[(task, seed)]["group"] for seed in range(10, 15)]
        # Seeds 10-11, 12-13 and 14 alone (the cell's last block).
        assert groups[0] == groups[1] != groups[2] == groups[3] != groups[4]
        assert [records[(task, s)]["concurrent"] for s in range(10, 15)] == [2, 2, 2, 2, 1]
    assert all(r["started_together"] for r in records.values())
    calls = [json.loads(line) for line in log.read_text().splitlines()]
    by_kb: dict[str, list[dict[str, object]]] = {}
    for call in calls:
        by_kb.setdefault(str(call["kb"]), []).append(call)
    assert sorted(len(c) for c in by_kb.values()) == [1, 1, 2, 2, 2, 2]
    # A group's runs ran at once, each in its own worker (the pool grew to N).
    assert all(len({c["pid"] for c in group}) == len(group) for group in by_kb.values())
    kb_points = sorted(records[(t, s)]["kb_points_before"] for t in ("desk",) for s in (10, 11))
    assert kb_points[-1] <= 1  # each saw at most the other's one point, no other group's


def test_concurrent_runs_refuse_predecessors_and_another_n_in_the_same_out(
    tmp_path: Path,
) -> None:
    run = functools.partial(toy_run_with_kb, log_path=str(tmp_path / "calls.jsonl"))
    transfer = expand(["desk"], ["cp-bo-transfer"], range(2))
    with pytest.raises(ValueError, match="cp-bo-transfer"):
        run_bench(transfer, tmp_path / "a", run, workers=2, max_rollouts=10, concurrent=2)
    alone = expand(["desk"], ["cp-bo"], range(2))
    with pytest.raises(ValueError, match="service"):
        run_bench(alone, tmp_path / "b", run, workers=2, max_rollouts=10, concurrent=2)
    ResultStore(tmp_path / "c").pin_config(
        {"max_rollouts": 10, "predecessor_rollouts": 30, "config": {}}
    )
    never_asked = ServiceKbs("http://127.0.0.1:9")  # the settings are refused before
    with pytest.raises(BenchConfigError, match="concurrent"):
        run_bench(
            alone,
            tmp_path / "c",
            run,
            workers=2,
            max_rollouts=10,
            kb_service=never_asked,
            concurrent=2,
        )

"""`cpkb bench --concurrent N [--mixed]`: groups, records, and the summary against alone."""

from __future__ import annotations

import functools
import json
from dataclasses import replace
from pathlib import Path

import pytest
from bench_toy_planner import toy_run_with_kb

from cpkb.bench.app import BenchSettings, run_command
from cpkb.bench.results import ResultStore
from cpkb.bench.runner import _grouped
from cpkb.bench.scenarios import expand
from cpkb.bench.together import GroupCheck, summarize_together


def test_mixed_groups_take_each_seeds_tasks_in_turn() -> None:
    scenarios = expand(["desk", "regrasp", "pack"], ["cp-bo"], range(3))
    groups = _grouped(scenarios, scenarios, 3, mixed=True)
    assert [[(s.task, s.seed) for s in g] for g in groups] == [
        [("desk", s), ("regrasp", s), ("pack", s)] for s in range(3)
    ]
    pairs = _grouped(scenarios, scenarios[1:], 2, mixed=True)  # a rerun keeps the blocks
    assert [[(s.task, s.seed) for s in g] for g in pairs][:2] == [
        [("regrasp", 0)],
        [("pack", 0), ("desk", 1)],
    ]


def _record(task: str, seed: int, rollouts: int, **extra: object) -> dict[str, object]:
    return {"task": task, "method": "cp-bo", "seed": seed, "solved": True,
            "rollouts": rollouts, "wall_s": 1.0, "kb_s": 0.1, **extra}  # fmt: skip


def test_the_summary_pairs_each_run_with_the_same_seed_alone() -> None:
    alone = [_record(t, s, 40) for t in ("desk", "pack") for s in range(4)]
    parts = {"kb_parts": {"suggest": 0.2, "match": 0.1}, "live_points": 6, "concurrent": 2}
    together = [
        _record(t, s, 10 * (1 + s % 2), **parts) for t in ("desk", "pack") for s in range(4)
    ]
    together.append(_record("desk", 9, 1))  # no partner alone: left out
    rows = summarize_together(together, alone, ["desk", "pack"], ["cp-bo"])
    assert [(r.task, r.n) for r in rows] == [("desk", 4), ("pack", 4), ("all", 8)]
    desk = rows[0]
    assert (desk.alone_mean, desk.together_mean, desk.concurrent) == (40.0, 15.0, 2)
    assert desk.ratio == pytest.approx(0.375)
    low, high = desk.ratio_ci
    assert 0.25 <= low <= 0.375 <= high <= 0.5
    assert list(desk.together_kb_parts) == ["match", "suggest"] and desk.live_points == 6
    check = GroupCheck.of(
        [
            {"group": "g1", "points_posted": 5, "points_stored": 5},
            {"group": "g2", "points_posted": 5, "points_stored": 6},
        ]
    )
    assert (check.points_posted, check.points_stored, check.mismatched) == (10, 11, ["g2"])
    assert "MISMATCH" in check.line()


@pytest.mark.slow
def test_a_mixed_bench_runs_the_seeds_alone_then_together_and_compares(tmp_path: Path) -> None:
    run = functools.partial(toy_run_with_kb, log_path=str(tmp_path / "calls.jsonl"))
    out = tmp_path / "out"
    settings = BenchSettings(
        tasks=["desk", "pack"],
        methods=["cp-bo"],
        seeds=range(2),
        workers=2,
        out_dir=out,
        max_rollouts=50,
        quiet=True,
        concurrent=2,
        mixed=True,
    )
    assert run_command(settings, run) == 0
    alone = ResultStore(out / "alone").records()
    assert sorted((r["task"], r["seed"]) for r in alone) == [
        ("desk", 0), ("desk", 1), ("pack", 0), ("pack", 1)
    ]  # fmt: skip
    assert all("group" not in r and r["kb_points_before"] == 0 for r in alone)
    together = ResultStore(out).records()
    groups: dict[str, set[tuple[str, int]]] = {}
    for r in together:
        assert r["mixed"] is True and r["concurrent"] == 2 and r["started_together"]
        groups.setdefault(r["group"], set()).add((r["task"], r["seed"]))
    assert sorted(map(sorted, groups.values())) == [[("desk", s), ("pack", s)] for s in range(2)]
    checks = ResultStore(out).groups()
    assert len(checks) == 2
    assert all(c["points_posted"] == c["points_stored"] == 2 for c in checks)
    summary = (out / "summary_concurrent.md").read_text()
    assert "| desk | cp-bo | 2 mixed | 2 |" in summary and "| all | cp-bo |" in summary
    assert "4 points posted, 4 stored (none lost or doubled)" in summary
    assert json.loads((out / "bench.json").read_text())["mixed"] is True
    calls = [json.loads(line) for line in (tmp_path / "calls.jsonl").read_text().splitlines()]
    assert len(calls) == 8  # each seed alone, then together: nothing run twice
    assert run_command(settings, run) == 0  # a rerun has nothing left to run
    assert len((tmp_path / "calls.jsonl").read_text().splitlines()) == 8
    # Another arm with other settings compares with the same alone runs, only read.
    other = replace(settings, out_dir=tmp_path / "other", alone_dir=out / "alone", max_rollouts=60)
    assert run_command(other, run) == 0
    assert len((tmp_path / "calls.jsonl").read_text().splitlines()) == 12
    assert "| all | cp-bo |" in (tmp_path / "other" / "summary_concurrent.md").read_text()

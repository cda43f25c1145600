"""The harness: scenario expansion, the worker pool, predecessors, resumability, time limit."""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from bench_toy_planner import toy_run
from wait_support import wait_until

from cpkb.bench.results import BenchConfigError, ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import Scenario, expand


def _calls(log: Path) -> list[dict]:
    if not log.exists():
        return []
    return [json.loads(line) for line in log.read_text().splitlines()]


def test_expand_is_seed_major_and_checks_transfer_tasks() -> None:
    scenarios = expand(["desk", "pack"], ["quasi-random", "cp-bo-transfer"], range(2))
    assert scenarios[:4] == [
        Scenario("desk", "quasi-random", 0),
        Scenario("desk", "cp-bo-transfer", 0),
        Scenario("pack", "quasi-random", 0),
        Scenario("pack", "cp-bo-transfer", 0),
    ]
    assert {s.seed for s in scenarios[4:]} == {1}
    assert Scenario("regrasp", "cp-bo-transfer", 0).predecessors == ("deskP", "desk")
    assert Scenario("regrasp", "cp-bo-transfer", 0).sampler == "cp-bo"
    assert Scenario("desk", "cp-bo", 0).predecessors == ()
    with pytest.raises(ValueError, match="no predecessor tasks for 'deskP'"):
        expand(["deskP"], ["cp-bo-transfer"], range(1))


def test_pool_runs_every_scenario_once_with_predecessors_first(tmp_path: Path) -> None:
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log))
    scenarios = expand(["desk", "regrasp"], ["quasi-random", "cp-bo", "cp-bo-transfer"], range(3))
    outcome = run_bench(
        scenarios,
        tmp_path / "out",
        run,
        workers=2,
        max_rollouts=500,
        predecessor_rollouts=30,
        predecessor_kwargs={"stop_at_first": False},
    )
    assert (outcome.finished, outcome.errors, outcome.remaining) == (18, 0, 0)
    records = ResultStore(tmp_path / "out").records()
    assert sorted((r["task"], r["method"], r["seed"]) for r in records) == sorted(
        s.key for s in scenarios
    )
    for r in records:
        assert r["max_rollouts"] == 500 and 1 <= r["rollouts"] <= 500
        assert {"wall_s", "sim_s", "kb_s", "solved", "scenario_wall_s"} <= set(r)
    transfer = [r for r in records if r["method"] == "cp-bo-transfer"]
    assert all(r["sampler"] == "cp-bo" for r in transfer)
    assert {
        tuple(p["task"] for p in r["predecessors"]) for r in transfer if r["task"] == "regrasp"
    } == {("deskP", "desk")}
    # The worker ran the predecessors before the target, with the whole 30-rollout budget.
    calls = _calls(log)
    by_pid_seed: dict[tuple[int, int], list[dict]] = {}
    for c in calls:
        if c["method"] == "cp-bo" and c["max_rollouts"] == 30:
            assert c["stop_at_first"] is False
        by_pid_seed.setdefault((c["pid"], c["seed"]), []).append(c)
    regrasp_target = [
        c
        for c in calls
        if c["task"] == "regrasp" and c["method"] == "cp-bo" and c["max_rollouts"] == 500
    ]
    assert len(regrasp_target) == 6  # cp-bo and cp-bo-transfer, three seeds each
    predecessor_calls = [c for c in calls if c["max_rollouts"] == 30]
    assert [c["task"] for c in predecessor_calls].count("deskP") == 6
    pids = {c["pid"] for c in calls}  # worker processes, at most the pool's two (a loaded
    assert 1 <= len(pids) <= 2 and os.getpid() not in pids  # machine may start one late)


def test_paper_transfer_runs_its_predecessors_and_target_with_the_paper_method(
    tmp_path: Path,
) -> None:
    assert Scenario("pack", "cp-bo-paper-transfer", 0).sampler == "cp-bo-paper"
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log))
    scenarios = expand(["desk"], ["cp-bo-paper-transfer"], range(2))
    outcome = run_bench(scenarios, tmp_path / "out", run, workers=1, max_rollouts=100)
    assert (outcome.finished, outcome.errors) == (2, 0)
    calls = _calls(log)
    assert [(c["task"], c["method"]) for c in calls] == [
        ("deskP", "cp-bo-paper"),
        ("desk", "cp-bo-paper"),
    ] * 2
    records = ResultStore(tmp_path / "out").records()
    assert {r["sampler"] for r in records} == {"cp-bo-paper"}
    assert all([p["task"] for p in r["predecessors"]] == ["deskP"] for r in records)


def test_rerun_skips_finished_runs_and_redoes_a_line_cut_short(tmp_path: Path) -> None:
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log))
    out = tmp_path / "out"
    scenarios = expand(["desk"], ["quasi-random", "cp-bo"], range(4))
    run_bench(scenarios, out, run, workers=2, max_rollouts=200)
    assert len(_calls(log)) == 8
    again = run_bench(scenarios, out, run, workers=2, max_rollouts=200)
    assert (again.skipped, again.finished) == (8, 0)
    assert len(_calls(log)) == 8
    # A kill mid-write leaves half a line: that run is redone, the others are kept.
    runs = out / "runs.jsonl"
    lines = runs.read_text().splitlines()
    runs.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][: len(lines[-1]) // 2])
    third = run_bench(scenarios, out, run, workers=1, max_rollouts=200)
    assert (third.skipped, third.finished) == (7, 1)
    assert len(ResultStore(out).records()) == 8
    # More seeds later: only the new ones run.
    more = run_bench(
        expand(["desk"], ["quasi-random", "cp-bo"], range(5)), out, run, workers=2, max_rollouts=200
    )
    assert (more.skipped, more.finished) == (8, 2)


def test_rerun_with_another_rollout_cap_is_refused(tmp_path: Path) -> None:
    run = functools.partial(toy_run, log_path=str(tmp_path / "calls.jsonl"))
    scenarios = expand(["desk"], ["quasi-random"], range(1))
    run_bench(scenarios, tmp_path / "out", run, workers=1, max_rollouts=200)
    with pytest.raises(BenchConfigError, match="max_rollouts: 200 here, 300 asked"):
        run_bench(scenarios, tmp_path / "out", run, workers=1, max_rollouts=300)


@pytest.mark.slow
def test_time_limit_stops_and_a_rerun_finishes(tmp_path: Path) -> None:
    """Seed 0's two runs are quick, every later one outlasts the limit: the limit must stop
    the bench with exactly seed 0 recorded, however long a loaded machine takes to start."""
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log), sleep_s=600.0, sleep_seeds=range(1, 6))
    out = tmp_path / "out"
    scenarios = expand(["desk"], ["quasi-random", "cp-bo"], range(6))
    first = run_bench(scenarios, out, run, workers=1, max_rollouts=100, time_limit_s=30)
    assert first.timed_out
    assert (first.finished, first.remaining) == (2, 10)
    assert {r["seed"] for r in ResultStore(out).records()} == {0}
    quick = functools.partial(toy_run, log_path=str(log))
    second = run_bench(scenarios, out, quick, workers=2, max_rollouts=100)
    assert not second.timed_out
    assert (second.skipped, second.finished) == (2, 10)
    assert len(ResultStore(out).records()) == 12


def test_a_failing_run_is_reported_and_retried(tmp_path: Path) -> None:
    log = tmp_path / "calls.jsonl"
    out = tmp_path / "out"
    scenarios = expand(["desk"], ["quasi-random"], range(3))
    failing = functools.partial(toy_run, log_path=str(log), fail_seeds=(1,))
    outcome = run_bench(scenarios, out, failing, workers=2, max_rollouts=100)
    assert (outcome.finished, outcome.errors) == (2, 1)
    assert "RuntimeError: toy failure on seed 1" in outcome.error_messages[0]
    store = ResultStore(out)
    assert [e["seed"] for e in store.errors()] == [1]
    assert "Traceback" in store.errors()[0]["traceback"]
    fixed = run_bench(
        scenarios, out, functools.partial(toy_run, log_path=str(log)), workers=1, max_rollouts=100
    )
    assert (fixed.skipped, fixed.finished) == (2, 1)


def test_workers_leave_when_the_bench_process_is_killed(tmp_path: Path) -> None:
    """SIGKILL gives the bench no chance to stop its pool: the workers notice and leave."""
    log = tmp_path / "calls.jsonl"
    script = (
        "import functools, sys\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from bench_toy_planner import toy_run\n"
        "from cpkb.bench.runner import run_bench\n"
        "from cpkb.bench.scenarios import expand\n"
        "if __name__ == '__main__':\n"
        f"    run = functools.partial(toy_run, log_path={str(log)!r}, sleep_s=60.0)\n"
        f"    run_bench(expand(['desk'], ['cp-bo'], range(4)), {str(tmp_path / 'out')!r}, run,\n"
        "              workers=2, max_rollouts=10)\n"
    )
    bench = subprocess.Popen([sys.executable, "-c", script], cwd=Path(__file__).parents[3])
    try:
        wait_until(lambda: len(_calls(log)) >= 2, interval=0.2, what="two runs starting")
        pids = {c["pid"] for c in _calls(log)}
        assert len(pids) == 2
    finally:
        bench.kill()
        bench.wait()
    wait_until(
        lambda: not any(_alive(pid) for pid in pids), interval=0.2, what="the workers leaving"
    )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").exists() and "Z" not in _state(pid)


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2]
    except (OSError, IndexError):
        return "Z"

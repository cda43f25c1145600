"""`cpkb bench --cores N`: a method without knowledge runs N trees at once, the first binding
winning, its rollouts summed over the trees; a guided method's planner and service share the
same N cores."""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import pytest
from bench_toy_planner import toy_run

from cpkb.bench.app import BenchSettings, check_request, portfolio_methods, service_env
from cpkb.bench.portfolio import Portfolio, tree_seeds
from cpkb.bench.results import ResultStore
from cpkb.bench.runner import run_bench
from cpkb.bench.scenarios import expand

COMMON = {"kb_url": None, "kb": None, "quiet": True}


def _calls(log: Path) -> list[dict]:
    return [json.loads(line) for line in log.read_text().splitlines()]


def test_the_trees_are_seeded_from_the_runs_seed_and_the_first_keeps_it():
    assert tree_seeds(7, 3) == tree_seeds(7, 3)
    assert tree_seeds(7, 3)[0] == 7 and tree_seeds(7, 1) == [7]
    assert len(set(tree_seeds(7, 4))) == 4
    assert tree_seeds(8, 3)[1:] != tree_seeds(7, 3)[1:]


def test_the_first_binding_wins_and_the_stopped_trees_count_what_they_ran(tmp_path: Path):
    """Trees 1 and 2 sleep before their first rollout: tree 0 wins with the rollouts it
    would take alone, and the sleepers, stopped, add none."""
    log = tmp_path / "calls.jsonl"
    seeds = tree_seeds(7, 3)
    run = functools.partial(toy_run, log_path=str(log), sleep_s=600.0, sleep_seeds=seeds[1:])
    result = Portfolio(run, 3)("desk", "quasi-random", 7, max_rollouts=300, **COMMON)
    alone = toy_run("desk", "quasi-random", 7, max_rollouts=100, log_path=str(log), **COMMON)
    assert alone["solved"] and result["solved"]
    assert result["portfolio"]["winner"] == 0
    assert result["portfolio"]["rollouts"] == [alone["rollouts"], 0, 0]
    assert result["rollouts"] == alone["rollouts"]
    trees = _calls(log)[:-1]  # those that got to start before tree 0 won; the last: alone
    assert 7 in {c["seed"] for c in trees} and {c["seed"] for c in trees} <= set(seeds)
    assert {c["max_rollouts"] for c in trees} == {100}  # the cap shared out


def test_racing_trees_sum_the_winners_rollouts_and_every_others(tmp_path: Path):
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log))
    result = Portfolio(run, 3)("desk", "quasi-random", 11, max_rollouts=600, **COMMON)
    winner = result["portfolio"]["winner"]
    counts = result["portfolio"]["rollouts"]
    seed = tree_seeds(11, 3)[winner]
    alone = toy_run("desk", "quasi-random", seed, max_rollouts=200, log_path=str(log), **COMMON)
    assert result["solved"] and counts[winner] == alone["rollouts"]
    assert all(0 <= count <= 200 for count in counts)
    assert result["rollouts"] == result["rollouts_spent"] == sum(counts)
    assert result["wall_s"] == pytest.approx(float(alone["wall_s"]), abs=60.0)  # the winner's


def test_an_unsolved_portfolio_spends_the_runs_cap_over_its_trees(tmp_path: Path):
    run = functools.partial(toy_run, log_path=str(tmp_path / "calls.jsonl"))
    result = Portfolio(run, 3)("never", "quasi-random", 3, max_rollouts=90, **COMMON)
    assert not result["solved"] and result["portfolio"]["winner"] is None
    assert result["portfolio"]["rollouts"] == [30, 30, 30]
    assert result["rollouts"] == 90


def test_a_failing_tree_fails_the_run(tmp_path: Path):
    seeds = tree_seeds(5, 2)
    run = functools.partial(toy_run, log_path=str(tmp_path / "calls.jsonl"), fail_seeds=(seeds[1],))
    with pytest.raises(RuntimeError, match=f"tree 1 \\(seed {seeds[1]}\\) failed.*toy failure"):
        Portfolio(run, 2)("never", "quasi-random", 5, max_rollouts=10_000_000, **COMMON)


def test_methods_without_knowledge_run_as_portfolios():
    settings = BenchSettings(
        tasks=["desk"],
        methods=["quasi-random", "quasi-random-restarts", "mcts-bo", "cp-bo", "cp-bo-transfer"],
        seeds=range(1),
        workers=1,
        out_dir="unused",
        cores=2,
    )
    assert portfolio_methods(settings) == {"quasi-random", "quasi-random-restarts", "mcts-bo"}


def test_the_service_counts_among_a_runs_cores():
    assert service_env((0, 1, 2)) == {"CPKB_CPU_CORES": "1-2"}
    assert service_env((3,)) == {"CPKB_CPU_CORES": "3"}  # one core: the planner's own


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"workers": 2}, "use --workers 1"),
        ({"cores": 10_000}, "may use only"),
        ({"kb_url": "http://127.0.0.1:1"}, "not with --kb-url"),
        ({"service_cores": "shared"}, "not with --service-cores shared"),
    ],
)
def test_a_cores_bench_that_cannot_count_its_cores_is_refused(changes: dict, message: str):
    base = {"tasks": ["desk"], "methods": ["quasi-random"], "seeds": range(1), "workers": 1}
    settings = BenchSettings(**{**base, "out_dir": "unused", "cores": 1, **changes})
    with pytest.raises(ValueError, match=message):
        check_request(settings)


def test_a_cores_bench_pins_the_planner_and_each_tree_to_its_core(tmp_path: Path):
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) < 2:
        pytest.skip("needs two cores to place two trees")
    cores = tuple(allowed[:2])
    log = tmp_path / "calls.jsonl"
    run = functools.partial(toy_run, log_path=str(log))
    scenarios = expand(["desk"], ["quasi-random", "cp-bo"], range(2))
    outcome = run_bench(
        scenarios,
        tmp_path / "out",
        run,
        workers=1,
        max_rollouts=400,
        cores=cores,
        portfolio={"quasi-random"},
    )
    assert (outcome.finished, outcome.errors) == (4, 0)
    records = {(r["method"], r["seed"]): r for r in ResultStore(tmp_path / "out").records()}
    for seed in range(2):
        tree = records[("quasi-random", seed)]["portfolio"]
        assert tree["trees"] == 2 and tree["cores"] == list(cores)
        assert tree["seeds"] == tree_seeds(seed, 2)
        assert "portfolio" not in records[("cp-bo", seed)]
    assert {r["cores"] for r in records.values()} == {2}
    calls = _calls(log)
    assert {tuple(c["cpus"]) for c in calls if c["method"] == "cp-bo"} == {cores[:1]}
    # Each tree that got to start ran on its own core (a tree may be stopped before it
    # starts: the toy's winner can finish first); the winner always started.
    tree_core = {
        seed: core for run in range(2) for seed, core in zip(tree_seeds(run, 2), cores, strict=True)
    }
    tree_cpus = {c["seed"]: c["cpus"] for c in calls if c["method"] == "quasi-random"}
    assert all(cpus == [tree_core[seed]] for seed, cpus in tree_cpus.items())
    for seed in range(2):
        tree = records[("quasi-random", seed)]["portfolio"]
        assert tree["seeds"][tree["winner"]] in tree_cpus
    pinned = json.loads((tmp_path / "out" / "bench.json").read_text())["cores"]
    assert pinned == 2


@pytest.mark.slow
def test_a_planner_portfolios_winner_took_the_rollouts_its_tree_takes_alone():
    from cpkb.bench.app import plan_run

    portfolio = Portfolio(plan_run, 2)
    result = portfolio("analytic:desk", "quasi-random-restarts", 4, max_rollouts=400, **COMMON)
    winner = result["portfolio"]["winner"]
    seed = tree_seeds(4, 2)[winner]
    alone = plan_run("analytic:desk", "quasi-random-restarts", seed, max_rollouts=200, **COMMON)
    counts = result["portfolio"]["rollouts"]
    assert result["solved"] and counts[winner] == alone.rollouts
    assert result["rollouts"] == sum(counts)
    assert result["config"]["search"]["restart_without_knowledge"] is True

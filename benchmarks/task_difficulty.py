"""How hard each task is: the fraction of fully random bindings that pass, where random ones
fail, and (with --plan-seeds) rollouts to the first feasible binding under quasi-random PW-UCT.

Used to tune the scenes so that a guided planner has something to save: mean rollouts of at
least 10 on desk and 20 on regrasp and pack, with 99% of runs solved within 2,000.
Writes benchmarks/results/task_difficulty.json.

    .venv/bin/python benchmarks/task_difficulty.py --bindings 200 --plan-seeds 5 --tasks desk,pack
"""

from __future__ import annotations

import argparse
import json
import statistics
from collections import Counter
from pathlib import Path

import numpy as np

from planner.sim import load_world
from planner.tasks import list_tasks

RESULTS = Path(__file__).parent / "results" / "task_difficulty.json"


def random_bindings(task: str, n: int, seed: int) -> dict:
    """Bind every decision uniformly at random; count full passes and where the rest fail."""
    world = load_world(task, seed=seed)
    rng = np.random.default_rng(seed)
    failures: Counter[str] = Counter()
    passed = 0
    try:
        for _ in range(n):
            state, bindings = world.initial_state(), {}
            for index, decision in enumerate(world.skeleton.decisions):
                if decision.kind == "#dir":
                    bindings[decision.var] = str(rng.choice(decision.domain.choices))
                else:
                    bindings[decision.var] = [float(v) for v in rng.uniform(size=3)]
                outcome = world.transition(index, bindings, state)
                if not outcome.ok:
                    failed = outcome.failed
                    what = failed.culprits[0].body if failed.culprits else "no collision"
                    failures[f"layer {index} {failed.call.name} ({what})"] += 1
                    break
                state = outcome.state
            else:
                passed += 1
    finally:
        world.close()
    return {
        "bindings": n,
        "feasible_fraction": passed / n,
        "failures": dict(failures.most_common()),
    }


def planned(task: str, seeds: int, max_rollouts: int) -> dict:
    from planner.run import run_plan

    runs = [run_plan(task, "quasi-random", s, max_rollouts=max_rollouts) for s in range(seeds)]
    rollouts = [r.rollouts for r in runs]
    return {
        "seeds": seeds,
        "solved": sum(r.solved for r in runs),
        "rollouts": rollouts,
        "mean_rollouts": statistics.mean(rollouts),
        "median_wall_s": statistics.median(r.wall_s for r in runs),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bindings", type=int, default=200)
    parser.add_argument("--plan-seeds", type=int, default=0)
    parser.add_argument("--max-rollouts", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tasks", default=",".join(t.name for t in list_tasks()))
    args = parser.parse_args()
    rows = []
    for task in args.tasks.split(","):
        row = {"task": task, "random": random_bindings(task, args.bindings, args.seed)}
        if args.plan_seeds:
            row["quasi_random_pwuct"] = planned(task, args.plan_seeds, args.max_rollouts)
        rows.append(row)
        plan = row.get("quasi_random_pwuct")
        extra = f"  PW-UCT rollouts {plan['rollouts']}" if plan else ""
        print(
            f"{task:8} random feasible {row['random']['feasible_fraction']:.3f}{extra}", flush=True
        )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({"seed": args.seed, "tasks": rows}, indent=2))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()

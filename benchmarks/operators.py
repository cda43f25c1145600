"""Median time of each operator and of a full rollout per task (random bindings, seeded).

A rollout binds every decision of the skeleton at random and runs the transitions until the
first failure or the end, as one PW-UCT rollout does. Writes benchmarks/results/operators.json.

    .venv/bin/python benchmarks/operators.py --rollouts 60 --seed 0
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from planner.sim import load_world
from planner.tasks import list_tasks

RESULTS = Path(__file__).parent / "results" / "operators.json"


def random_value(kind: str, choices: list[str], rng: np.random.Generator) -> object:
    if kind == "#dir":
        return str(rng.choice(choices))
    return [float(v) for v in rng.uniform(size=3)]


def measure(task: str, rollouts: int, seed: int) -> dict:
    world = load_world(task, seed=seed)
    rng = np.random.default_rng(seed)
    per_op: dict[str, list[float]] = defaultdict(list)
    rollout_s: list[float] = []
    feasible = 0
    try:
        for _ in range(rollouts):
            state, bindings = world.initial_state(), {}
            started = time.perf_counter()
            for index, decision in enumerate(world.skeleton.decisions):
                choices = getattr(decision.domain, "choices", [])
                bindings[decision.var] = random_value(decision.kind, choices, rng)
                layer_start = time.perf_counter()
                outcome = world.transition(index, bindings, state)
                per_op["transition layer"].append(time.perf_counter() - layer_start)
                for check in outcome.checks:
                    if "seconds" in check.detail:
                        per_op[check.call.name].append(check.detail["seconds"])
                if not outcome.ok:
                    break
                state = outcome.state
            else:
                feasible += 1
            rollout_s.append(time.perf_counter() - started)
    finally:
        world.close()
    return {
        "task": task,
        "rollouts": rollouts,
        "feasible_fraction": feasible / rollouts,
        "rollout_median_ms": 1000 * statistics.median(rollout_s),
        "operator_median_ms": {k: 1000 * statistics.median(v) for k, v in sorted(per_op.items())},
        "operator_calls": {k: len(v) for k, v in sorted(per_op.items())},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rollouts", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tasks", default=",".join(t.name for t in list_tasks()))
    args = parser.parse_args()
    rows = [measure(t, args.rollouts, args.seed) for t in args.tasks.split(",")]
    for row in rows:
        ops = ", ".join(f"{k} {v:.1f}" for k, v in row["operator_median_ms"].items())
        print(
            f"{row['task']:8} rollout {row['rollout_median_ms']:6.1f} ms  "
            f"feasible {row['feasible_fraction']:.3f}  [{ops}]"
        )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({"seed": args.seed, "tasks": rows}, indent=2))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()

"""What a rollout costs in the planner's own CPU time, per method, against the baseline's.

`rollout_cost.py` reads a bench's wall times, which a loaded machine stretches by how many
processes share its cores, and stretches a guided run more than a quasi-random one (the service's
fits compete with it). This runs each task x method x seed here, one after the other, each on a
fresh knowledge base of an embedded service (on the other cores, as `cpkb plan` has it), through a
fixed number of rollouts (`stop_at_first=False`), and counts this process's CPU time (every thread
of the planner, not the service's) beside the wall time: the CPU time per rollout is what the wall
time would be where the planner has a core to itself.

    .venv/bin/python benchmarks/rollout_cpu.py --tasks benchmarks/suites/dev-hard \
        --methods quasi-random-restarts,cp-bo --seeds 52100-52100 --rollouts 150
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from cpkb.bench.scenarios import BASELINE_METHOD, seed_range
from cpkb.embedded import embedded_service
from planner.run import run_plan


def _targets(tasks: str) -> list[Path]:
    """Task files, a suite directory standing for its targets (the files without `_pre`)."""
    found: list[Path] = []
    for item in (t for t in tasks.split(",") if t):
        path = Path(item)
        if path.is_dir():
            found += sorted(
                p
                for p in path.glob("*/*.yaml")
                if "_pre" not in p.stem and p.name != "workspace.yaml"
            )
        else:
            found.append(path)
    return found


def measure(task: Path, method: str, seed: int, rollouts: int) -> tuple[int, float, float]:
    """(rollouts run, wall s, this process's CPU s) of one run."""
    with (
        tempfile.TemporaryDirectory(prefix="rollout-cpu-") as tmp,
        embedded_service(f"sqlite:///{tmp}/kb.db", planner_cores=1) as url,
    ):
        wall, cpu = time.perf_counter(), time.process_time()
        result = run_plan(
            task, method, seed, kb_url=url, max_rollouts=rollouts, stop_at_first=False
        )
        return result.rollouts, time.perf_counter() - wall, time.process_time() - cpu


def table(totals: dict[str, list[float]], methods: list[str]) -> str:
    lines = [
        "| method | runs | rollouts | ms per rollout: wall | CPU | wall / baseline's | "
        "CPU / baseline's |",
        "|---|---|---|---|---|---|---|",
    ]
    base = totals.get(BASELINE_METHOD)
    for method in methods:
        runs, done, wall, cpu = totals[method]
        ms_wall, ms_cpu = 1000 * wall / done, 1000 * cpu / done
        if base is None or method == BASELINE_METHOD:
            ratios = "- | -"
        else:
            ratios = f"{ms_wall / (1000 * base[2] / base[1]):.2f} | "
            ratios += f"{ms_cpu / (1000 * base[3] / base[1]):.2f}"
        lines.append(
            f"| {method} | {runs:.0f} | {done:.0f} | {ms_wall:.1f} | {ms_cpu:.1f} | {ratios} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", required=True, help="task files or suite directories")
    parser.add_argument("--methods", default=f"{BASELINE_METHOD},cp-bo")
    parser.add_argument("--seeds", type=seed_range, default=range(52100, 52101), help="FIRST-LAST")
    parser.add_argument("--rollouts", type=int, default=150, help="rollouts a run (150)")
    args = parser.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    tasks = _targets(args.tasks)
    if not tasks or args.rollouts < 1:
        print("no tasks, or --rollouts below 1", file=sys.stderr)
        return 2
    totals: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0, 0.0])
    for task in tasks:
        for seed in args.seeds:
            for method in methods:
                done, wall, cpu = measure(task, method, seed, args.rollouts)
                print(
                    f"{task} {method} {seed}: {done} rollouts, {wall:.1f} s wall, {cpu:.1f} s CPU"
                )
                cell = totals[method]
                cell[0] += 1
                cell[1] += done
                cell[2] += wall
                cell[3] += cpu
    print(table(totals, methods))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Goal-only tasks run twice in one knowledge base, paired by seed: solved within the time
budget on the first (cold) run, and how much sooner the second (warm) run finds its first
binding list. Each (task, seed) gets a knowledge base of its own, so the warm run knows only
its cold twin's run. Runs are what `cpkb plan` does (`planner.run.run_plan`), in this one
process, against a service given by URL (`cpkb serve`).

    .venv/bin/python benchmarks/warm_goals.py --kb-url http://127.0.0.1:8123 \\
        --out benchmarks/results/external2 --seeds 20 \\
        benchmarks/suites/external/blocked/blocked.yaml ...
    .venv/bin/python benchmarks/warm_goals.py --summarize benchmarks/results/external2
"""

from __future__ import annotations

import argparse
import json
import lzma
import os
import statistics
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

RUNS = "runs.jsonl"


def run(args: argparse.Namespace) -> None:
    from planner.run import run_plan
    from planner.tasks import load_task

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = {str(p): load_task(str(p)).name for p in args.tasks}
    with (out / RUNS).open("a") as log:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            for path, name in names.items():
                kb = f"{args.tag}-{name}-{seed}"
                for attempt in ("cold", "warm"):
                    load = os.getloadavg()[0]
                    result = run_plan(
                        path,
                        args.method,
                        seed,
                        kb_url=args.kb_url,
                        kb=kb,
                        max_rollouts=args.max_rollouts,
                        time_budget_s=args.time_budget,
                    )
                    record = {
                        "task": name,
                        "seed": seed,
                        "run": attempt,
                        "method": args.method,
                        "kb": kb,
                        "solved": result.solved,
                        "wall_s": result.wall_s,
                        "rollouts": result.rollouts,
                        "notes": result.notes,
                        "load1": load,
                        "finished": time.strftime("%H:%M:%S", time.gmtime()),
                    }
                    log.write(json.dumps(record) + "\n")
                    log.flush()
                    print(name, seed, attempt, result.solved, f"{result.wall_s:.1f}s", flush=True)


def read(folder: Path) -> list[dict[str, Any]]:
    plain, packed = folder / RUNS, folder / f"{RUNS}.xz"
    text = plain.read_text() if plain.exists() else lzma.decompress(packed.read_bytes()).decode()
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def summarize(folder: Path, budget: float) -> str:
    pairs: dict[str, dict[int, dict[str, dict[str, Any]]]] = defaultdict(lambda: defaultdict(dict))
    for r in read(folder):
        pairs[r["task"]][r["seed"]][r["run"]] = r
    lines = [
        "| task | seeds | cold solved within "
        f"{budget:.0f} s | cold median wall | warm median wall | median warm/cold "
        "| pairs halved | median rollouts cold -> warm | load (1 min) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for task, seeds in pairs.items():
        done = [s for s in seeds.values() if "cold" in s and "warm" in s]
        cold = [s["cold"] for s in done]
        warm = [s["warm"] for s in done]
        within = sum(r["solved"] and r["wall_s"] <= budget for r in cold)
        both = [s for s in done if s["cold"]["solved"] and s["warm"]["solved"]]
        ratios = [s["warm"]["wall_s"] / s["cold"]["wall_s"] for s in both]
        halved = sum(r <= 0.5 for r in ratios)
        loads = [r["load1"] for r in cold + warm]
        lines.append(
            f"| {task} | {len(done)} | {within} | "
            f"{statistics.median(r['wall_s'] for r in cold):.1f} s | "
            f"{statistics.median(r['wall_s'] for r in warm):.1f} s | "
            f"{statistics.median(ratios):.2f} | {halved} of {len(ratios)} | "
            f"{statistics.median(r['rollouts'] for r in cold):g} -> "
            f"{statistics.median(r['rollouts'] for r in warm):g} | "
            f"{min(loads):.0f}-{max(loads):.0f} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tasks", nargs="*", type=Path)
    parser.add_argument("--kb-url")
    parser.add_argument("--out", default="external2")
    parser.add_argument("--method", default="cp-bo")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--max-rollouts", type=int, default=2000)
    parser.add_argument("--time-budget", type=float, default=60.0)
    parser.add_argument("--tag", default="warm", help="prefix of the knowledge bases' names")
    parser.add_argument("--summarize", type=Path, metavar="DIR", help="print DIR's table")
    args = parser.parse_args()
    if args.summarize is not None:
        print(summarize(args.summarize, args.time_budget), end="")
        return
    if args.kb_url is None or not args.tasks:
        parser.error("give the tasks and --kb-url (or --summarize DIR)")
    run(args)


if __name__ == "__main__":
    main()

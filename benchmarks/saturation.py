"""Knowledge saturates: desk's rollouts on a well-stocked knowledge base (DESIGN.md section 6).

Stocks one knowledge base with `--stock` earlier runs each of deskP and desk (cp-bo, to their
first feasible binding list), lets the service fit every type, then runs desk `--runs` times
more with cp-bo on new seeds and reports their rollouts (each measured run adds its own points,
as a planner in daily use would). The bar: at most 3 rollouts on average after ten of each.

    .venv/bin/python benchmarks/saturation.py [--stock 10] [--runs 10] [--out benchmarks/results]

Writes <out>/saturation.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from cpkb.bench.kbs import ServiceKbs
from cpkb.embedded import embedded_service
from planner.run import run_plan

KB = "stocked"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stock", type=int, default=10, help="earlier runs of deskP and of desk")
    parser.add_argument("--runs", type=int, default=10, help="measured desk runs")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    with (
        tempfile.TemporaryDirectory(prefix="cpkb-saturation-") as tmp,
        embedded_service(f"sqlite:///{Path(tmp) / 'kb.db'}") as url,
    ):
        kbs = ServiceKbs(url)
        kbs.create(KB)
        stock = []
        for seed in range(args.stock):
            for task in ("deskP", "desk"):
                r = run_plan(task, "cp-bo", seed, kb_url=url, kb=KB)
                stock.append({"task": task, "seed": seed, "rollouts": r.rollouts})
        waited = kbs.wait_fitted(KB)
        measured = []
        for seed in range(1000, 1000 + args.runs):
            r = run_plan("desk", "cp-bo", seed, kb_url=url, kb=KB)
            measured.append({"seed": seed, "rollouts": r.rollouts, "solved": r.solved})
            kbs.wait_fitted(KB)
    rollouts = [m["rollouts"] for m in measured]
    result = {
        "stock_runs_each": args.stock,
        "fit_wait_s": waited,
        "stock": stock,
        "measured": measured,
        "mean_rollouts": statistics.mean(rollouts),
        "median_rollouts": statistics.median(rollouts),
        "bar_mean_at_most": 3,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "saturation.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "stock"}, indent=2))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

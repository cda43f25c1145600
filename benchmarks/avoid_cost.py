"""What keeping away from pending points costs one suggestion.

A planner's own batches leave pending points behind (served, not answered yet), and every
suggestion checks them and measures its candidates against them. This times, for a grasp plus
a 3-D placement with `--pending` pending points (and 5 excluded siblings), the construction of
the `AvoidSet` and one whole `maximize_batch` of 4 points on a flat acquisition, median of
`--repeats`.

    .venv/bin/python benchmarks/avoid_cost.py [--pending 70] [--out benchmarks/results]

Writes <out>/avoid_cost.json (with the commit it ran at) and prints it.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from surrogate.acquisition import PendingPoints, Scored
from surrogate.avoid import AvoidSet
from surrogate.config import OptimizerConfig
from surrogate.domains import CategoricalDomain, ContinuousDomain
from surrogate.optimize import maximize_batch

SPACE = {
    "#dir2": CategoricalDomain(choices=["top", "front", "back", "left", "right"]),
    "#pose12": ContinuousDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0]),
}


def _median_ms(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        times.append(1000 * (time.perf_counter() - started))
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pending", type=int, default=70)
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    pending = [
        {"#dir2": str(rng.choice(["top", "front"])), "#pose12": [float(v) for v in rng.random(3)]}
        for _ in range(args.pending)
    ]
    exclude = pending[:5]

    def flat(cols: dict) -> np.ndarray:
        return np.full(len(cols["#pose12"]), 0.4)

    acquisition = Scored(flat, pending=PendingPoints(tuple(pending)))
    config = OptimizerConfig()
    result = {
        "pending": args.pending,
        "repeats": args.repeats,
        "commit": subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip(),
        "avoid_set_ms": _median_ms(lambda: AvoidSet(SPACE, {}, exclude, pending), args.repeats),
        "maximize_batch_ms": _median_ms(
            lambda: maximize_batch(acquisition, SPACE, exclude=exclude, config=config, n=4),
            args.repeats,
        ),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "avoid_cost.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

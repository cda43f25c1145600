"""Fit time and held-out AUC of a type's classifier against its number of points.

A synthetic constraint on [0, 1]^5 (feasible inside a disc of two coordinates, above a floor in a
third, outside a corner of the last two: about 30 % feasible), n training points, 5,000 held-out
ones. Per n: the service's fit (at most `max_fit_points` trained on) cold and warm (from a fit on
the first 95 % of the points, as the service refits after new points); the same fit on all the
points (`max_points=0`, the fit before issue 19) where affordable; and an exact GP (GP regression
on +-1 labels, `fit_label_regression`) where affordable.

    nice -n 10 .venv/bin/python benchmarks/fit_scaling.py

Writes benchmarks/results/fit_scaling.json and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from sklearn.metrics import roc_auc_score

from server.surrogates.engine import FIT_THREADS
from surrogate.config import SurrogateConfig
from surrogate.models import Fit, fit_classifier, fit_label_regression, use_threads, warm_up

RESULTS = Path(__file__).resolve().parent / "results"
DIM = 5


def constraint(z: np.ndarray) -> np.ndarray:
    """The synthetic ground truth: True where feasible."""
    disc = np.hypot(z[:, 0] - 0.5, z[:, 1] - 0.5) < 0.35
    corner = (z[:, 3] > 0.7) & (z[:, 4] < 0.3)
    return disc & (z[:, 2] > 0.2) & ~corner


def _timed(fit_fn: Callable[[], Fit], zt: np.ndarray, yt: np.ndarray) -> dict[str, Any]:
    """One fit: wall seconds, CPU seconds of this process (what the fit costs, whatever else
    the machine runs: fits use one thread, as in the fit worker), held-out AUC and what it
    trained on."""
    cpu = time.process_time()
    fit = fit_fn()
    cpu = time.process_time() - cpu
    return {
        "seconds": round(fit.fit_seconds, 4),
        "cpu_seconds": round(cpu, 4),
        "auc": round(float(roc_auc_score(yt, fit.predictor.proba(zt))), 5),
        "iterations": fit.iterations,
        "n_trained": fit.n_trained,
        "n_inducing": fit.n_inducing,
    }


def measure(n: int, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    z = rng.random((n, DIM))
    zt = rng.random((args.test, DIM))
    y, yt = constraint(z), constraint(zt)
    row: dict[str, Any] = {"n": n, "seed": seed, "feasible_share": round(float(y.mean()), 3)}
    row["cold"] = _timed(lambda: fit_classifier(z, y, seed=seed), zt, yt)
    earlier = fit_classifier(z[: int(0.95 * n)], y[: int(0.95 * n)], seed=seed)
    row["warm"] = _timed(lambda: fit_classifier(z, y, seed=seed, warm=earlier), zt, yt)
    if n <= args.unbounded_max:
        row["all_points"] = _timed(lambda: fit_classifier(z, y, seed=seed, max_points=0), zt, yt)
    if n <= args.exact_max:
        row["exact"] = _timed(lambda: fit_label_regression(z, y, seed=seed), zt, yt)
    row["loadavg_1m"] = round(os.getloadavg()[0], 2)
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="100,300,1000,2000,5000,10000,20000,50000")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--test", type=int, default=5000, help="held-out points")
    parser.add_argument("--exact-max", type=int, default=2000, help="largest n for the exact GP")
    parser.add_argument("--unbounded-max", type=int, default=10000, help="... for all points")
    parser.add_argument("--out", type=Path, default=RESULTS / "fit_scaling.json")
    args = parser.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    use_threads(FIT_THREADS)  # as the service's fit worker runs
    warm_up()
    rows = []
    for n in sizes:
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            rows.append(measure(n, seed, args))
            print(json.dumps(rows[-1]), f"({time.perf_counter() - t0:.0f} s)", flush=True)
    result = {
        "command": " ".join(["benchmarks/fit_scaling.py", *(argv or sys.argv[1:])]),
        "when": datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ"),
        "max_fit_points": SurrogateConfig().max_fit_points,
        "max_inducing": SurrogateConfig().max_inducing,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

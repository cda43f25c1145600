"""Synthetic CP-BO benchmark (no simulator): MPF against the space-filling sampler, suggest latency
through the real service while points arrive, and fit time against points.

Three analytic constraints over a mixed space (a grasp direction with its approach-vector
embedding, and a box x, y in [0, 1], yaw in [-pi, pi]); their intersection is ~13% of the space.

    .venv/bin/python benchmarks/synthetic_cpbo.py [--quick | --full] [--out benchmarks/results]

Prints every table in one run and writes them to <out>/synthetic_cpbo.txt.
"""

from __future__ import annotations

import argparse
import io
import math
import os
import sys
import threading
import time
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import numpy as np

from contract.models import CategoricalDomain, ContinuousDomain
from surrogate.acquisition import MPF, ConstraintTerm
from surrogate.config import OptimizerConfig
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder
from surrogate.models import fit_classifier, fit_label_regression, warm_up
from surrogate.optimize import maximize, space_filling

DIRS = ["front", "right", "top", "back", "left"]
APPROACH = {
    "front": [1.0, 0.0, 0.0],
    "right": [0.0, -1.0, 0.0],
    "top": [0.0, 0.0, 1.0],
    "back": [-1.0, 0.0, 0.0],
    "left": [0.0, 1.0, 0.0],
}
DIR = CategoricalDomain(choices=DIRS, embedding=APPROACH)
POSE = ContinuousDomain(low=[0.0, 0.0, -math.pi], high=[1.0, 1.0, math.pi])
SPACE = space_from_json({"#dir": DIR.model_dump(), "#pose": POSE.model_dump()})
BIND = {"#dir": "#dir", "#pose": "#pose"}


def reach(c: dict[str, np.ndarray]) -> np.ndarray:
    return (c["#pose"][:, 0] - 0.6) ** 2 + (c["#pose"][:, 1] - 0.5) ** 2 < 0.35**2


def clear(c: dict[str, np.ndarray]) -> np.ndarray:
    side = np.isin(c["#dir"], [DIRS.index("right"), DIRS.index("left")])
    return ~(side & (c["#pose"][:, 0] < 0.5)) & (c["#dir"] != DIRS.index("back"))


def yaw(c: dict[str, np.ndarray]) -> np.ndarray:
    return np.abs(c["#pose"][:, 2] - 0.5) < 1.5


CONSTRAINTS = {"reach": reach, "clear": clear, "yaw": yaw}
ENCODER = SpaceEncoder(SPACE)


def truly_feasible(x: dict[str, Any]) -> bool:
    cols = ENCODER.columns([x])
    return all(bool(check(cols)[0]) for check in CONSTRAINTS.values())


# --- 1. feasible fraction --------------------------------------------------------------------
def mpf_of(fits: dict[str, Any]) -> MPF:
    return MPF([ConstraintTerm.build(n, f.predictor, SPACE, BIND, {}) for n, f in fits.items()])


def feasible_fraction(
    checkpoints: list[int], n_eval: int, refit_every: int, seed: int
) -> list[dict[str, Any]]:
    """A planner-like loop: suggest with MPF, label the point by every constraint, post it to
    every type, refit (warm) every few points; at each checkpoint, `n_eval` fresh suggestions
    of each method are checked against the truth."""
    xs: list[dict[str, Any]] = []
    fits: dict[str, Any] = {}
    rows = []
    for step in range(max(checkpoints) + 1):
        if step in checkpoints:
            cols = ENCODER.columns(xs)
            z = ENCODER.encode(cols)
            fits = {
                n: fit_classifier(z, c(cols), seed=seed, warm=fits.get(n))
                for n, c in CONSTRAINTS.items()
            }
            label_fits = {
                n: fit_label_regression(z, c(cols), seed=seed) for n, c in CONSTRAINTS.items()
            }
            row = {"points": step}
            for name, acq in (("mpf", mpf_of(fits)), ("mpf_label_regression", mpf_of(label_fits))):
                hits = [
                    truly_feasible(maximize(acq, SPACE, exclude=xs, seed=seed + 1000 + k).x)
                    for k in range(n_eval)
                ]
                row[name] = float(np.mean(hits))
            hits = [
                truly_feasible(space_filling(SPACE, exclude=xs, seed=seed + 2000 + k))
                for k in range(n_eval)
            ]
            row["space_filling"] = float(np.mean(hits))
            rows.append(row)
        if step == max(checkpoints):
            break
        if step % refit_every == 0 and len(xs) >= 4:
            cols = ENCODER.columns(xs)
            z = ENCODER.encode(cols)
            fits = {
                n: fit_classifier(z, c(cols), seed=seed, warm=fits.get(n))
                for n, c in CONSTRAINTS.items()
            }
        if fits:
            xs.append(maximize(mpf_of(fits), SPACE, exclude=xs, seed=seed + step).x)
        else:
            xs.append(space_filling(SPACE, exclude=xs, seed=seed + step))
    return rows


def optimizer_cut(n_points: int, seeds: int, seed: int) -> list[dict[str, Any]]:
    """MPF value and time reached by the default NSGA-II budget and by the authors' one."""
    rng = np.random.default_rng(seed)
    xs = [
        {
            "#dir": DIRS[int(rng.integers(5))],
            "#pose": [float(rng.random()), float(rng.random()), float(rng.uniform(-3, 3))],
        }
        for _ in range(n_points)
    ]
    cols = ENCODER.columns(xs)
    z = ENCODER.encode(cols)
    acq = mpf_of({n: fit_classifier(z, c(cols), seed=seed) for n, c in CONSTRAINTS.items()})
    rows = []
    for name, cfg in (("default", OptimizerConfig()), ("authors", OptimizerConfig.authors())):
        values, times = [], []
        for k in range(seeds):
            t0 = time.perf_counter()
            values.append(maximize(acq, SPACE, seed=k, config=cfg).value)
            times.append(time.perf_counter() - t0)
        rows.append(
            {
                "config": f"{name} pop {cfg.pop_size} x {cfg.generations} gen",
                "mpf_mean": float(np.mean(values)),
                "mpf_min": float(np.min(values)),
                "ms_p50": 1000 * float(np.median(times)),
            }
        )
    return rows


# --- 2. fit time against points --------------------------------------------------------------
def fit_times(sizes: list[int], seed: int) -> list[dict[str, Any]]:
    rng = np.random.default_rng(seed)
    rows = []
    for n in sizes:
        xs = [
            {
                "#dir": DIRS[int(rng.integers(5))],
                "#pose": [float(rng.random()), float(rng.random()), float(rng.uniform(-3, 3))],
            }
            for _ in range(n + 20)
        ]
        cols = ENCODER.columns(xs)
        z, y = ENCODER.encode(cols), reach(cols) & clear(cols)
        cold = fit_classifier(z[:n], y[:n], seed=seed)
        warm = fit_classifier(z, y, seed=seed, warm=cold)
        recold = fit_classifier(z, y, seed=seed)
        rows.append(
            {
                "points": n,
                "cold_s": cold.fit_seconds,
                "cold_iters": cold.iterations,
                "warm_s_after_20": warm.fit_seconds,
                "warm_iters": warm.iterations,
                "cold_s_after_20": recold.fit_seconds,
                "ms_per_point": 1000 * cold.fit_seconds / n,
            }
        )
    return rows


# --- 3. suggest latency through the service ---------------------------------------------------
def graph(i: int) -> dict[str, Any]:
    dom = {"kind": "categorical", "choices": DIRS, "embedding": APPROACH}
    pose = {"kind": "continuous", "low": POSE.low, "high": POSE.high}
    return {
        "nodes": [
            {"id": "f", "role": "failure", "label": f"check{i}"},
            {"id": "d", "role": "decision", "label": "#dir", "domain": dom},
            {"id": "p", "role": "decision", "label": "#pose", "domain": pose},
        ],
        "edges": [
            {"source": "d", "target": "f", "label": "grasp"},
            {"source": "p", "target": "f", "label": "pose"},
        ],
    }


def random_points(n: int, n_types: int, rng: np.random.Generator) -> list[dict[str, Any]]:
    out = []
    for _ in range(n):
        x = {
            "#dir": DIRS[int(rng.integers(5))],
            "#pose": [float(rng.random()), float(rng.random()), float(rng.uniform(-3, 3))],
        }
        cols = ENCODER.columns([x])
        checks = list(CONSTRAINTS.values())
        for t in range(n_types):
            out.append({"graph": graph(t), "x": x, "feasible": bool(checks[t % 3](cols)[0])})
    return out


def latency(cells: list[tuple[int, int]], n_suggest: int, seed: int) -> list[dict[str, Any]]:
    from client.client import CpkbClient
    from cpkb.embedded import embedded_service

    rows = []
    db = Path(os.environ.get("TMPDIR", "/tmp")) / f"cpkb-bench-{os.getpid()}.sqlite"
    with embedded_service(f"sqlite:///{db}") as url, CpkbClient(url, timeout=120) as client:
        for n_types, n_points in cells:
            kb = f"t{n_types}n{n_points}"
            client.create_kb(kb, exist_ok=True)
            rng = np.random.default_rng(seed)
            client.post_points(kb, random_points(n_points, n_types, rng))
            ids = sorted(t.type_id for t in client.list_types(kb))
            t0 = time.perf_counter()
            while any(
                (s := client.get_type(kb, t).surrogate) is None
                or s.status != "ready"
                or s.n_fitted < n_points
                for t in ids
            ):
                time.sleep(0.5)
            settle_s = time.perf_counter() - t0
            stop = threading.Event()

            def keep_posting(
                kb: str = kb, n_types: int = n_types, stop: threading.Event = stop
            ) -> None:
                arrive = np.random.default_rng(seed + 1)
                while not stop.is_set():
                    client.post_points(kb, random_points(2, n_types, arrive))
                    stop.wait(0.25)

            poster = threading.Thread(target=keep_posting)
            poster.start()
            body = {
                "space": {"#dir": DIR.model_dump(), "#pose": POSE.model_dump()},
                "constraints": [{"type_id": t, "bind": BIND} for t in ids],
            }
            times = []
            for k in range(n_suggest):
                t1 = time.perf_counter()
                client.suggest(kb, {**body, "seed": k})
                times.append(time.perf_counter() - t1)
            stop.set()
            poster.join()
            rows.append(
                {
                    "types": n_types,
                    "points_per_type": n_points,
                    "p50_ms": 1000 * float(np.percentile(times, 50)),
                    "p95_ms": 1000 * float(np.percentile(times, 95)),
                    "initial_fits_s": settle_s,
                }
            )
    db.unlink(missing_ok=True)
    return rows


def table(title: str, rows: list[dict[str, Any]]) -> None:
    print(f"\n## {title}")
    if not rows:
        return
    keys = list(rows[0])
    print(" | ".join(keys))
    for row in rows:
        print(
            " | ".join(f"{row[k]:.3f}" if isinstance(row[k], float) else str(row[k]) for k in keys)
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    parser.add_argument("--full", action="store_true", help="add 3,000/10,000-point sizes (long)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    quick = args.quick
    buffer = io.StringIO()
    started = time.perf_counter()

    class Tee(io.TextIOBase):
        def write(self, s: str) -> int:
            sys.__stdout__.write(s)
            sys.__stdout__.flush()
            return buffer.write(s)

    with redirect_stdout(Tee()):
        print("# synthetic CP-BO benchmark")
        print(f"machine: {os.cpu_count()} cores, load average at start {os.getloadavg()}")
        print(f"warm-up (first fit in a fresh process): {warm_up():.2f} s")
        checkpoints = [10, 30] if quick else [10, 30, 100]
        table(
            "fraction of truly feasible suggestions (same data, same seeds; ~13% of the "
            "space is feasible)",
            feasible_fraction(checkpoints, 10 if quick else 20, 5, args.seed),
        )
        table(
            "NSGA-II budget: MPF value reached (100 points per type)",
            optimizer_cut(100, 3 if quick else 5, args.seed),
        )
        table(
            "fit time against points (VGP classifier, <=128 inducing points)",
            fit_times([100, 300] if quick else [100, 300, 1000] + [3000] * args.full, args.seed),
        )
        cells = [(1, 100), (3, 100), (3, 1000)]
        if not quick:
            cells = [(1, 100), (3, 100), (10, 100), (1, 1000), (3, 1000)]
        if args.full:
            cells += [(10, 1000), (1, 10000), (3, 10000), (10, 10000)]
        table(
            "suggest latency through the service (HTTP, sqlite, fits in a child process) "
            "while points keep arriving",
            latency(cells, 15 if quick else 40, args.seed),
        )
        print(
            f"\nload average at end {os.getloadavg()}; total {time.perf_counter() - started:.0f} s"
        )
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "synthetic_cpbo.txt").write_text(buffer.getvalue())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

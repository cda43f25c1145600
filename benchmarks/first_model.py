"""How good a suggestion is right after a new type's first points, against after its fit.

A synthetic workspace of two constraint types over a grasp direction and a pose in [0, 1]^3
(`reach`: pose x above 0.35 and not from the back; `clear`: pose (y, z) within 0.3 of the
centre or x above 0.8). Per trial, a fresh knowledge base gets 60 random points of each type in
one post; once both types have a model, or after `--first-wait` (1 s), `--asks` suggestions are
asked one after the other (each checked against the
ground truth), then, once both background fits have landed, as many again. Each trial also
records when the type first had a model (any fit) and when the background fit landed.

    nice -n 10 .venv/bin/python benchmarks/first_model.py
    nice -n 10 .venv/bin/python benchmarks/first_model.py --instant-fit-points 0  # before

Starts `cpkb serve` itself on a fresh SQLite file; writes
benchmarks/results/first_model-<instant>.json and prints a summary.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx

from cpkb.embedded import embedded_service
from surrogate.config import SurrogateConfig

RESULTS = Path(__file__).resolve().parent / "results"
DIRECTIONS = ["front", "right", "top", "back", "left"]
DIR = {"kind": "categorical", "choices": DIRECTIONS}
POSE = {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]}


def _graph(failure: str, context: str) -> dict[str, Any]:
    nodes = [
        {"id": "f", "role": "failure", "label": failure},
        {"id": "d0", "role": "decision", "label": "#dir", "domain": DIR},
        {"id": "d1", "role": "decision", "label": "#pose", "domain": POSE},
        {"id": "c0", "role": "context", "label": context},
    ]
    edges = [
        {"source": "d0", "target": "f", "label": "feeds"},
        {"source": "d1", "target": "f", "label": "feeds"},
        {"source": "c0", "target": "f", "label": "collides"},
    ]
    return {"nodes": nodes, "edges": edges}


def reach(direction: str, pose: list[float]) -> bool:
    return pose[0] > 0.35 and direction != "back"


def clear(direction: str, pose: list[float]) -> bool:
    return math.hypot(pose[1] - 0.5, pose[2] - 0.5) < 0.3 or pose[0] > 0.8


TYPES = {
    "reach": (_graph("Inv-kin", "shelf"), reach),
    "clear": (_graph("Plan-motion", "box"), clear),
}


def _states(http: httpx.Client, kb: str, ids: dict[str, str]) -> dict[str, dict]:
    return {n: http.get(f"/v1/kbs/{kb}/types/{t}").json()["surrogate"] for n, t in ids.items()}


def _ask(http: httpx.Client, kb: str, ids: dict[str, str], seed: int) -> dict[str, Any]:
    body = {
        "space": {"dir": DIR, "pose": POSE},
        "constraints": [
            {"type_id": t, "bind": {"#dir": "dir", "#pose": "pose"}} for t in ids.values()
        ],
        "seed": seed,
    }
    start = time.perf_counter()
    answer = http.post(f"/v1/kbs/{kb}/suggest", json=body).raise_for_status().json()
    x = answer["x"]
    ok = all(truth(x["dir"], x["pose"]) for _, truth in TYPES.values())
    return {"feasible": ok, "ms": round(1000 * (time.perf_counter() - start), 1)}


def _modelled(state: dict, n: int) -> bool:
    """Whether a type's state shows a model (any fit, not the prior) of all its points."""
    return state["n_fitted"] == n and state["kind"] != "prior"


def trial(http: httpx.Client, index: int, args: argparse.Namespace) -> dict[str, Any]:
    rng = random.Random(index)
    kb = f"first-{index}-{os.getpid()}"
    http.post("/v1/kbs", json={"name": kb}).raise_for_status()
    points = []
    for _ in range(args.points):
        direction, pose = rng.choice(DIRECTIONS), [rng.random() for _ in range(3)]
        for graph, truth in TYPES.values():
            points.append(
                {
                    "graph": graph,
                    "x": {"#dir": direction, "#pose": pose},
                    "feasible": truth(direction, pose),
                }
            )
    posted = http.post(f"/v1/kbs/{kb}/points", json={"points": points}).raise_for_status().json()
    t0 = time.monotonic()
    ids = dict(zip(TYPES, [r["type_id"] for r in posted["results"][:2]], strict=True))
    first_model_s = landed_s = None
    while first_model_s is None and time.monotonic() - t0 < args.first_wait:
        if all(_modelled(s, args.points) for s in _states(http, kb, ids).values()):
            first_model_s = round(time.monotonic() - t0, 3)
        time.sleep(0.02)
    early = []
    for i in range(args.asks):
        row = _ask(http, kb, ids, seed=1000 * index + i)
        row["at_s"] = round(time.monotonic() - t0, 2)
        row["kinds"] = sorted({s["kind"] for s in _states(http, kb, ids).values()})
        early.append(row)
    while time.monotonic() - t0 < args.timeout:
        states = _states(http, kb, ids).values()
        if all(s["kind"] == "vgp" and s["n_fitted"] == args.points for s in states):
            landed_s = round(time.monotonic() - t0, 2)
            break
        time.sleep(0.05)
    late = [_ask(http, kb, ids, seed=1000 * index + 500 + i) for i in range(args.asks)]
    return {
        "trial": index,
        "first_model_s": first_model_s,  # None: none within --first-wait
        "background_fit_s": landed_s,
        "early": early,
        "late": late,
        "early_feasible": sum(r["feasible"] for r in early) / len(early),
        "late_feasible": sum(r["feasible"] for r in late) / len(late),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--points", type=int, default=60, help="first points per type")
    parser.add_argument("--asks", type=int, default=10, help="suggestions per phase")
    parser.add_argument(
        "--instant-fit-points", type=int, default=SurrogateConfig().instant_fit_points
    )
    parser.add_argument("--timeout", type=float, default=300.0)
    parser.add_argument(
        "--first-wait", type=float, default=1.0, help="seconds to wait for a first model"
    )
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    env = {"CPKB_SURROGATE__INSTANT_FIT_POINTS": str(args.instant_fit_points)}
    trials = []
    with (
        tempfile.TemporaryDirectory(prefix="cpkb-first-") as tmp,
        embedded_service(f"sqlite:///{tmp}/kb.sqlite", env=env) as url,
        httpx.Client(base_url=url, timeout=120) as http,
    ):
        for index in range(args.trials):
            t = trial(http, index, args)
            trials.append(t)
            print(
                f"trial {index}: first model {t['first_model_s']} s, "
                f"background fit {t['background_fit_s']} s, feasible right after ingest "
                f"{t['early_feasible']:.0%}, after the fit {t['late_feasible']:.0%}",
                flush=True,
            )
    early = [r["feasible"] for t in trials for r in t["early"]]
    late = [r["feasible"] for t in trials for r in t["late"]]
    result = {
        "command": " ".join(["benchmarks/first_model.py", *(argv or sys.argv[1:])]),
        "when": datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ"),
        "instant_fit_points": args.instant_fit_points,
        "points_per_type": args.points,
        "early_feasible": sum(early) / len(early),
        "late_feasible": sum(late) / len(late),
        "loadavg_1m_after": os.getloadavg()[0],
        "trials": trials,
    }
    out = args.out or RESULTS / f"first_model-instant{args.instant_fit_points}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(
        f"right after ingest {result['early_feasible']:.0%} feasible, "
        f"after the fit {result['late_feasible']:.0%}; wrote {out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Ingest throughput of the knowledge base: single-point posts and batches of 100.

Starts `cpkb serve` on a fresh database (a temporary SQLite file unless --db is given),
then, through `CpkbClient`, posts --singles points one request each and --batches batches
of 100 points, alternating the two kinds in rounds so that both see the same machine load.
Points are spread over three types, each with a unique idempotency key, as planners post them.
Writes a JSON result (points/s per mode, median and p95 request latency) to --out.

    .venv/bin/python benchmarks/ingest.py [--db URL] [--singles 500] [--batches 20]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from client import CpkbClient
from cpkb.embedded import embedded_service

DIRS = ["front", "right", "top", "back", "left"]


def graph(failure: str) -> dict[str, Any]:
    """A causal graph like a planner's: two decisions feed the failure, one obstacle."""
    return {
        "nodes": [
            {"id": "f", "role": "failure", "label": failure},
            {
                "id": "d",
                "role": "decision",
                "label": "#dir",
                "domain": {"kind": "categorical", "choices": DIRS},
            },
            {
                "id": "p",
                "role": "decision",
                "label": "#pose",
                "domain": {"kind": "continuous", "low": [0, 0, -3.2], "high": [1, 1, 3.2]},
            },
            {"id": "c", "role": "context", "label": "box1"},
        ],
        "edges": [
            {"source": "d", "target": "f", "label": "grasp"},
            {"source": "p", "target": "f", "label": "pose"},
            {"source": "c", "target": "f", "label": "collides"},
        ],
    }


GRAPHS = [graph(f) for f in ("Inv-kin", "Plan-motion", "Move-Place")]
BATCH = 100
ROUNDS = 10


def points(start: int, n: int) -> list[dict[str, Any]]:
    return [
        {
            "graph": GRAPHS[i % 3],
            "x": {"#dir": DIRS[i % 5], "#pose": [(i % 10) / 10, (i % 7) / 7, (i % 13) / 5 - 1.2]},
            "feasible": i % 3 == 0,
            "key": f"bench-{i}",
            "source": {"task": "bench", "rollout": i, "worker": "w0"},
        }
        for i in range(start, start + n)
    ]


def summary(latencies: list[float], n_points: int) -> dict[str, float]:
    ordered = sorted(latencies)
    return {
        "requests": len(latencies),
        "points": n_points,
        "points_per_s": n_points / sum(latencies),
        "latency_ms_p50": 1000 * statistics.median(ordered),
        "latency_ms_p95": 1000 * ordered[int(0.95 * (len(ordered) - 1))],
    }


def run(url: str, singles: int, batches: int) -> dict[str, Any]:
    single_lat: list[float] = []
    batch_lat: list[float] = []
    next_index = 0
    with CpkbClient(url, retries=0, timeout=120) as client:
        client.create_kb("bench")
        client.post_points("bench", points(10**9, 3))  # create the types outside the timing
        for round_ in range(ROUNDS):
            n_single = singles // ROUNDS + (round_ < singles % ROUNDS)
            n_batch = batches // ROUNDS + (round_ < batches % ROUNDS)
            for point in points(next_index, n_single):
                t = time.perf_counter()
                client.post_points("bench", [point])
                single_lat.append(time.perf_counter() - t)
            next_index += n_single
            for _ in range(n_batch):
                batch = points(next_index, BATCH)
                t = time.perf_counter()
                client.post_points("bench", batch)
                batch_lat.append(time.perf_counter() - t)
                next_index += BATCH
        stored = client.get_kb("bench").n_points
    expected = singles + batches * BATCH + 3
    if stored != expected:
        raise SystemExit(f"stored {stored} points, expected {expected}")
    single, batched = summary(single_lat, singles), summary(batch_lat, batches * BATCH)
    return {
        "single": single,
        "batch_100": batched,
        "batch_over_single": batched["points_per_s"] / single["points_per_s"],
        "stored": stored,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", help="database URL (default: a temporary SQLite file)")
    parser.add_argument("--singles", type=int, default=500)
    parser.add_argument("--batches", type=int, default=20)
    parser.add_argument("--out", type=Path, default=None, help="result file (JSON)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cpkb-ingest-") as tmp:
        db_url = args.db or f"sqlite:///{Path(tmp) / 'bench.sqlite'}"
        with embedded_service(db_url) as url:
            result = run(url, args.singles, args.batches)
    backend = db_url.split(":")[0].split("+")[0]
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    result = {
        "benchmark": "ingest",
        "backend": backend,
        "when": stamp,
        "machine": f"{platform.machine()}, {platform.python_version()}",
        **result,
    }
    out = args.out or Path(__file__).parent / "results" / f"ingest-{backend}-{stamp}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    print(f"written to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

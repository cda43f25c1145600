"""What one open dashboard tab costs the service: the overview's poll (`/ui/api/overview`) and
a type page's poll on a knowledge base with many types.

Starts `cpkb serve` on a fresh SQLite file with surrogate fits off (CPKB_SURROGATE__ENABLED=false,
so that fits do not load the machine while it measures), posts --types types of --points points
each (tasks and runs spread over them), then requests each poll URL --rounds times and writes
the median and p95 latency and the answer's size to --out as JSON.

    .venv/bin/python benchmarks/dashboard_poll.py [--types 500] [--points 4] [--rounds 20]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx

from client import CpkbClient
from cpkb.embedded import embedded_service


def _graph(k: int) -> dict[str, Any]:
    return {
        "nodes": [
            {"id": "f", "role": "failure", "label": "Inv-kin"},
            {
                "id": "d",
                "role": "decision",
                "label": "#pose",
                "domain": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
            },
            {"id": "c", "role": "context", "label": f"body{k}"},
        ],
        "edges": [
            {"source": "d", "target": "f", "label": "pose"},
            {"source": "c", "target": "f", "label": "collides"},
        ],
    }


def _stock(client: CpkbClient, n_types: int, n_points: int) -> str:
    points = [
        {
            "graph": _graph(k),
            "x": {"#pose": [0.1 * j, 0.5]},
            "feasible": j % 2 == 0,
            "source": {"task": f"task{k % 7}", "run": f"run{k % 13}", "worker": "bench"},
        }
        for k in range(n_types)
        for j in range(n_points)
    ]
    type_id = ""
    for start in range(0, len(points), 500):
        type_id = client.post_points("default", points[start : start + 500])[0].type_id
    return type_id


def _measure(url: str, rounds: int) -> dict[str, float]:
    seconds, size = [], 0
    with httpx.Client(timeout=120) as http:
        http.get(url).raise_for_status()  # warm caches and connections
        for _ in range(rounds):
            start = time.perf_counter()
            answer = http.get(url)
            seconds.append(time.perf_counter() - start)
            answer.raise_for_status()
            size = len(answer.content)
    seconds.sort()
    return {
        "median_s": statistics.median(seconds),
        "p95_s": seconds[min(len(seconds) - 1, int(0.95 * len(seconds)))],
        "bytes": size,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--types", type=int, default=500)
    parser.add_argument("--points", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'kb.sqlite'}"
        env = {"CPKB_SURROGATE__ENABLED": "false"}
        with embedded_service(db, env=env) as url, CpkbClient(url) as client:
            type_id = _stock(client, args.types, args.points)
            result = {
                "types": args.types,
                "points_per_type": args.points,
                "rounds": args.rounds,
                "at": datetime.now(UTC).isoformat(),
                "overview": _measure(f"{url}/ui/api/overview", args.rounds),
                "type_page": _measure(f"{url}/ui/api/kbs/default/types/{type_id}", args.rounds),
            }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()

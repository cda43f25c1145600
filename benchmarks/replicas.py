"""Replicas on one PostgreSQL: one `cpkb serve` against two, under the same planners.

Each planner (a thread with its own `CpkbClient`, given every replica's URL, rotated so that
planners start on different replicas) loops for `--duration` seconds: post a batch of failure
points over four causal graphs (its own node names), then ask for a suggestion constrained by
one of the types. Afterwards the script waits until every replica serves each type from a fit
of all its stored points, and reports: acknowledged and stored points (each key once), types,
post and suggest latency, fits made and fits loaded per replica (from /metrics), versions
fitted more than once (from the replicas' JSON logs), and how long the last fits took to land.

    nice -n 10 .venv/bin/python benchmarks/replicas.py --replicas 1,2 --planners 8 --duration 30

Starts the servers itself on fresh PostgreSQL databases (dropped afterwards) and writes a JSON
result file in benchmarks/results/.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from client import CpkbClient
from cpkb.embedded import wait_ready

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"
DEFAULT_PG_ADMIN = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
POSE = {"kind": "continuous", "low": [0.0, 0.0, -3.0], "high": [1.0, 1.0, 3.0]}
DIRS = {"kind": "categorical", "choices": ["front", "right", "top", "back", "left"]}
GRAPHS = [("Inv-kin", ["box1"]), ("Plan-motion", ["box1", "box2"]), ("Move-Place", ["shelf"])]
GRAPHS += [("Inv-kin", ["box2"])]
BATCH = 5


def graph(i: int, planner: int) -> dict[str, Any]:
    failure, context = GRAPHS[i]
    p = f"p{planner}-"
    nodes = [
        {"id": p + "f", "role": "failure", "label": failure},
        {"id": p + "d", "role": "decision", "label": "#dir", "domain": DIRS},
        {"id": p + "x", "role": "decision", "label": "#pose", "domain": POSE},
    ]
    edges = [
        {"source": p + "d", "target": p + "f", "label": "grasp"},
        {"source": p + "x", "target": p + "f", "label": "pose"},
    ]
    for j, body in enumerate(context):
        nodes.append({"id": f"{p}c{j}", "role": "context", "label": body})
        edges.append({"source": f"{p}c{j}", "target": p + "f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


def point(planner: int, n: int, rng: np.random.Generator) -> dict[str, Any]:
    pose = [float(rng.random()), float(rng.random()), float(rng.uniform(-3, 3))]
    direction = DIRS["choices"][int(rng.integers(5))]
    return {
        "graph": graph(n % len(GRAPHS), planner),
        "x": {"#dir": direction, "#pose": pose},
        "feasible": pose[0] + 0.3 * pose[1] > 0.6 and direction != "top",
        "key": f"planner{planner}-{n}",
        "source": {"task": "replicas-bench", "run": f"planner{planner}", "rollout": n},
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def fresh_database(admin_url: str) -> Iterator[str]:
    import psycopg
    from sqlalchemy.engine import make_url

    admin = make_url(admin_url)
    dsn = admin.set(drivername="postgresql").render_as_string(hide_password=False)
    name = f"cpkb_replicas_{uuid.uuid4().hex[:10]}"
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        yield admin.set(database=name).render_as_string(hide_password=False)
    finally:
        with psycopg.connect(dsn, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@contextmanager
def replicas(db_url: str, n: int, logs: Path) -> Iterator[list[tuple[str, Path]]]:
    """`n` `cpkb serve` processes on `db_url`: their URLs and log files."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("CPKB_")}
    procs, out = [], []
    try:
        for i in range(n):
            port, log = free_port(), logs / f"replica-{i}.log"
            cmd = [sys.executable, "-m", "cpkb", "serve", "--db", db_url, "--port", str(port)]
            with log.open("wb") as f:
                procs.append(
                    subprocess.Popen(
                        cmd,
                        env=env | {"CPKB_REPLICA_NAME": f"r{i}"},
                        stdout=f,
                        stderr=subprocess.STDOUT,
                        start_new_session=True,
                    )
                )
            out.append((f"http://127.0.0.1:{port}", log))
        for (url, log), proc in zip(out, procs, strict=True):
            if not wait_ready(url, proc, 300):
                raise RuntimeError(f"{url} did not start: {log.read_text()[-2000:]}")
        yield out
    finally:
        for proc in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)


def planner(
    number: int, urls: str, until: float, out: dict[str, Any], lock: threading.Lock
) -> None:
    rng = np.random.default_rng(number)
    posts, suggests, acknowledged, errors = [], [], [], []
    with CpkbClient(urls, timeout=60) as kb:
        n = 0
        while time.monotonic() < until:
            batch = [point(number, n + j, rng) for j in range(BATCH)]
            try:
                t0 = time.perf_counter()
                results = kb.post_points("default", batch)
                posts.append(time.perf_counter() - t0)
                acknowledged.extend(p["key"] for p in batch)
                t0 = time.perf_counter()
                kb.suggest(
                    "default",
                    {
                        "space": {"d": DIRS, "p": POSE},
                        "constraints": [
                            {"type_id": results[0].type_id, "bind": {"#dir": "d", "#pose": "p"}}
                        ],
                    },
                )
                suggests.append(time.perf_counter() - t0)
            except Exception as exc:  # counted in the result, the run goes on
                errors.append(f"{type(exc).__name__}: {exc}")
            n += BATCH
    with lock:
        out["posts"] += posts
        out["suggests"] += suggests
        out["acknowledged"] += acknowledged
        out["errors"] += errors


def metric(url: str, name: str) -> float:
    for line in httpx.get(f"{url}/metrics", timeout=30).text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return 0.0


def served_versions(urls: list[str]) -> bool:
    """Every replica serves each type from a fit of all its stored points."""
    types = httpx.get(f"{urls[0]}/v1/kbs/default/types", timeout=30).json()
    counts = {t["type_id"]: t["n_points"] for t in types}
    for url in urls:
        with CpkbClient(url) as kb:
            models = kb.models("default", list(counts)).models
        if any(m.n_fitted != counts[m.type_id] for m in models):
            return False
    return True


def stored_keys(url: str) -> Counter[str]:
    keys: Counter[str] = Counter()
    with CpkbClient(url) as kb:
        for t in kb.list_types("default"):
            keys.update(p.key for p in kb.iter_points("default", t.type_id) if p.key)
    return keys


def pct(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)) * 1000, 1) if values else float("nan")


def rotated(urls: list[str], i: int) -> str:
    """The replica URLs starting at planner `i`'s own, as a client takes them."""
    k = i % len(urls)
    return ",".join(urls[k:] + urls[:k])


def run(admin_url: str, n_replicas: int, planners: int, duration: float) -> dict[str, Any]:
    with (
        tempfile.TemporaryDirectory() as tmp,
        fresh_database(admin_url) as db_url,
        replicas(db_url, n_replicas, Path(tmp)) as servers,
    ):
        urls = [u for u, _ in servers]
        out: dict[str, Any] = {"posts": [], "suggests": [], "acknowledged": [], "errors": []}
        lock = threading.Lock()
        until = time.monotonic() + duration
        threads = [
            threading.Thread(target=planner, args=(i, rotated(urls, i), until, out, lock))
            for i in range(planners)
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        t0 = time.monotonic()
        while not served_versions(urls):
            if time.monotonic() - t0 > 600:
                raise RuntimeError("the replicas did not settle within 600 s")
            time.sleep(0.5)
        settle_s = time.monotonic() - t0
        keys = stored_keys(urls[0])
        fits = [metric(u, 'cpkb_surrogate_fits_total{outcome="ok"}') for u in urls]
        adopted = [metric(u, "cpkb_surrogate_fits_adopted_total") for u in urls]
        n_types = len(httpx.get(f"{urls[0]}/v1/kbs/default/types", timeout=30).json())
        fitted: Counter[tuple[str, int]] = Counter()
        for _, log in servers:
            for line in log.read_text(errors="replace").splitlines():
                if line.startswith("{") and '"fitted ' in line:
                    record = json.loads(line)
                    fitted[(record["type_id"], record["version"])] += 1
    acknowledged = out["acknowledged"]
    return {
        "replicas": n_replicas,
        "planners": planners,
        "duration_s": duration,
        "points_acknowledged": len(acknowledged),
        "points_stored": sum(keys.values()),
        "acknowledged_missing": len(set(acknowledged) - set(keys)),
        "keys_stored_twice": sum(1 for c in keys.values() if c > 1),
        "types": n_types,
        "points_per_s": round(len(acknowledged) / duration, 1),
        "post_ms_p50": pct(out["posts"], 50),
        "post_ms_p95": pct(out["posts"], 95),
        "suggest_ms_p50": pct(out["suggests"], 50),
        "suggest_ms_p95": pct(out["suggests"], 95),
        "errors": len(out["errors"]),
        "fits_per_replica": fits,
        "fits_adopted_per_replica": adopted,
        "versions_fitted": len(fitted),
        "versions_fitted_twice": sum(1 for c in fitted.values() if c > 1),
        "settle_s": round(settle_s, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicas", default="1,2", help="replica counts to run, e.g. 1,2")
    parser.add_argument("--planners", type=int, default=8)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--pg", default=os.environ.get("CPKB_TEST_POSTGRES_URL", DEFAULT_PG_ADMIN))
    args = parser.parse_args()
    rows = [run(args.pg, int(n), args.planners, args.duration) for n in args.replicas.split(",")]
    for row in rows:
        print(json.dumps(row))
    RESULTS.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    path = RESULTS / f"replicas-{args.planners}p-{stamp}.json"
    provenance = {
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "host": platform.node(),
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "time": stamp,
    }
    path.write_text(json.dumps({"provenance": provenance, "runs": rows}, indent=2) + "\n")
    print(f"wrote {path.relative_to(REPO)}")


if __name__ == "__main__":
    main()

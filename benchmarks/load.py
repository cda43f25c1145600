"""Load test: many simulated planners against one real knowledge-base server on loopback.

Each planner loops for `--duration` seconds: ask `suggest` for a grasp direction and a placement
under two known constraint types, then post the points a planner would learn from checking that
binding (one per type, each with its own idempotency key). A request that fails without an answer
is retried with the same key, as the client does. Afterwards every acknowledged key must be stored
exactly once, and nothing else stored at all.

    .venv/bin/python benchmarks/load.py --planners 8 --backend sqlite
    .venv/bin/python benchmarks/load.py --planners 32 --backend postgres
    .venv/bin/python benchmarks/load.py --planners 1 --writers 4 --seed-points 1000

`--writers N` adds N workers that post the same kind of points without pause and never ask
(the last line: suggestions on a 1,000-point type while its points keep pouring in).

Starts `cpkb serve` itself (fresh SQLite file, or a fresh PostgreSQL database that is dropped
afterwards), prints a table, and writes a JSON result file in benchmarks/results/.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import platform
import random
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from contract.models import MAX_POINTS_PER_POST
from cpkb.embedded import wait_ready

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"
DEFAULT_PG_ADMIN = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
DIRECTIONS = ["front", "right", "top", "back", "left"]
UNIT_BOX = {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]}
DIR_DOMAIN = {"kind": "categorical", "choices": DIRECTIONS}
RETRIES = 5


def _graph(failure: str, decisions: dict[str, dict[str, Any]], context: list[str]) -> dict:
    """A causal graph: decision vertexes feed the failure vertex, context vertexes touch it."""
    nodes = [{"id": "f", "role": "failure", "label": failure}]
    edges = []
    for i, (label, domain) in enumerate(decisions.items()):
        nodes.append({"id": f"d{i}", "role": "decision", "label": label, "domain": domain})
        edges.append({"source": f"d{i}", "target": "f", "label": "feeds"})
    for i, label in enumerate(context):
        nodes.append({"id": f"c{i}", "role": "context", "label": label})
        edges.append({"source": f"c{i}", "target": "f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


# Two constraint types of a desk-like workspace, with a ground truth that labels the points.
IK_GRAPH = _graph("Inv-kin", {"#dir": DIR_DOMAIN}, ["shelf"])
PLACE_GRAPH = _graph("Plan-motion", {"#dir": DIR_DOMAIN, "#pose": UNIT_BOX}, ["box1"])


def ik_feasible(direction: str) -> bool:
    return direction in ("front", "top", "right")


def place_feasible(direction: str, pose: list[float]) -> bool:
    return pose[0] > 0.3 and math.hypot(pose[1] - 0.5, pose[2] - 0.5) < 0.45 and direction != "back"


def random_x(rng: random.Random) -> tuple[str, list[float]]:
    return rng.choice(DIRECTIONS), [rng.random() for _ in range(3)]


def points_for(direction: str, pose: list[float], worker: str, seq: int) -> list[dict]:
    source = {"task": "load", "run": worker, "rollout": seq, "worker": worker}
    return [
        {
            "graph": IK_GRAPH,
            "x": {"#dir": direction},
            "feasible": ik_feasible(direction),
            "source": source,
            "key": f"{worker}-{seq}-ik",
        },
        {
            "graph": PLACE_GRAPH,
            "x": {"#dir": direction, "#pose": pose},
            "feasible": place_feasible(direction, pose),
            "source": source,
            "key": f"{worker}-{seq}-place",
        },
    ]


@dataclass
class Tally:
    """What the planners saw: latencies per endpoint, errors, and the keys acknowledged."""

    latencies: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    errors: Counter = field(default_factory=Counter)
    retries: Counter = field(default_factory=Counter)
    acknowledged: list[str] = field(default_factory=list)
    attempted: set[str] = field(default_factory=set)
    suggestions: int = 0


async def _call(
    http: httpx.AsyncClient, tally: Tally, name: str, method: str, url: str, body: dict
) -> httpx.Response | None:
    """One logical call with retries on transport errors and 5xx (same body, same keys)."""
    for attempt in range(RETRIES):
        start = time.perf_counter()
        try:
            response = await http.request(method, url, json=body)
        except httpx.TransportError as exc:
            tally.errors[f"{name}: {type(exc).__name__}"] += 1
        else:
            tally.latencies[name].append(time.perf_counter() - start)
            if response.status_code < 500:
                if response.status_code >= 400:
                    tally.errors[f"{name}: HTTP {response.status_code}"] += 1
                    return None
                return response
            tally.errors[f"{name}: HTTP {response.status_code}"] += 1
        tally.retries[name] += 1
        await asyncio.sleep(min(2.0, 0.05 * 2**attempt))
    return None


async def planner(
    http: httpx.AsyncClient,
    kb: str,
    type_ids: dict[str, str],
    worker: str,
    deadline: float,
    tally: Tally,
    seed: int,
    think_s: float,
    ask: bool,
) -> None:
    rng = random.Random(seed)
    suggest_body_base = {
        "space": {"dir": DIR_DOMAIN, "pose": UNIT_BOX},
        "constraints": [
            {"type_id": type_ids["ik"], "bind": {"#dir": "dir"}},
            {"type_id": type_ids["place"], "bind": {"#dir": "dir", "#pose": "pose"}},
        ],
    }
    seq = 0
    while time.monotonic() < deadline:
        seq += 1
        body = {**suggest_body_base, "seed": rng.randrange(2**31)}
        answer = None
        if ask:
            answer = await _call(http, tally, "suggest", "POST", f"/v1/kbs/{kb}/suggest", body)
        if answer is not None:
            tally.suggestions += 1
            x = answer.json()["x"]
            direction, pose = x["dir"], [float(v) for v in x["pose"]]
        else:
            direction, pose = random_x(rng)
        if think_s:
            await asyncio.sleep(think_s)
        points = points_for(direction, pose, worker, seq)
        keys = [p["key"] for p in points]
        tally.attempted.update(keys)
        posted = await _call(
            http, tally, "post_points", "POST", f"/v1/kbs/{kb}/points", {"points": points}
        )
        if posted is not None:
            tally.acknowledged.extend(keys)


async def seed_types(http: httpx.AsyncClient, kb: str, per_type: int, tally: Tally) -> dict:
    """Give both types some points before the clock starts, so suggest has surrogates to use."""
    rng = random.Random(0)
    points = [p for i in range(per_type) for p in points_for(*random_x(rng), worker="seed", seq=i)]
    tally.attempted.update(p["key"] for p in points)
    results = []
    for start in range(0, len(points), MAX_POINTS_PER_POST):
        batch = points[start : start + MAX_POINTS_PER_POST]
        response = await http.post(f"/v1/kbs/{kb}/points", json={"points": batch})
        response.raise_for_status()
        tally.acknowledged.extend(p["key"] for p in batch)
        results += response.json()["results"]
    return {"ik": results[0]["type_id"], "place": results[1]["type_id"]}


async def surrogate_states(http: httpx.AsyncClient, kb: str, type_ids: dict) -> dict:
    """Each type's surrogate state as its detail shows it (points, fitted, last fit's cost)."""
    out = {}
    for name, type_id in type_ids.items():
        detail = (await http.get(f"/v1/kbs/{kb}/types/{type_id}")).raise_for_status().json()
        out[name] = detail.get("surrogate")
    return out


async def wait_fitted(http: httpx.AsyncClient, kb: str, type_ids: dict, timeout: float) -> None:
    """Start the clock once the seeded types have their fits (or after `timeout`)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        states = await surrogate_states(http, kb, type_ids)
        if all(
            s and s.get("kind") == "vgp" and s.get("status") == "ready" for s in states.values()
        ):
            return
        await asyncio.sleep(0.5)


async def stored_keys(http: httpx.AsyncClient, kb: str) -> tuple[Counter, int]:
    """Every key stored in the knowledge base, paging through each type's points."""
    keys: Counter = Counter()
    stored = 0
    types = (await http.get(f"/v1/kbs/{kb}/types")).raise_for_status().json()
    for t in types:
        cursor = None
        while True:
            params: dict[str, Any] = {"limit": 1000}
            if cursor:
                params["cursor"] = cursor
            page = await http.get(f"/v1/kbs/{kb}/types/{t['type_id']}/points", params=params)
            page = page.raise_for_status().json()
            for point in page["points"]:
                stored += 1
                keys[point.get("key")] += 1
            cursor = page.get("next_cursor")
            if not cursor:
                break
    return keys, stored


async def run_load(base_url: str, args: argparse.Namespace, token: str | None) -> dict:
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    limits = httpx.Limits(
        max_connections=args.planners + args.writers + 4,
        max_keepalive_connections=args.planners + args.writers,
    )
    tally = Tally()
    async with httpx.AsyncClient(
        base_url=base_url, headers=headers, timeout=args.timeout, limits=limits
    ) as http:
        kb = f"load-{secrets.token_hex(3)}"
        (await http.post("/v1/kbs", json={"name": kb})).raise_for_status()
        type_ids = await seed_types(http, kb, args.seed_points, tally)
        seeded = len(tally.acknowledged)
        if not args.no_suggest:
            await wait_fitted(http, kb, type_ids, timeout=300)
        start = time.monotonic()
        deadline = start + args.duration
        askers = [
            planner(
                http,
                kb,
                type_ids,
                f"w{i:02d}",
                deadline,
                tally,
                args.seed + i,
                args.think,
                not args.no_suggest,
            )
            for i in range(args.planners)
        ]
        writers = [
            planner(
                http, kb, type_ids, f"p{i:02d}", deadline, tally, args.seed + 1000 + i, 0, False
            )
            for i in range(args.writers)
        ]
        await asyncio.gather(*askers, *writers)
        elapsed = time.monotonic() - start
        states = await surrogate_states(http, kb, type_ids)
        keys, stored = await stored_keys(http, kb)
        kb_row = next(
            (k for k in (await http.get("/v1/kbs")).json() if k["name"] == kb), {"n_points": None}
        )
    acknowledged = Counter(tally.acknowledged)
    check = {
        "acknowledged": len(acknowledged),
        "stored": stored,
        "kb_n_points": kb_row["n_points"],
        "acknowledged_missing": sum(1 for k in acknowledged if keys[k] == 0),
        "stored_twice": sum(1 for k, n in keys.items() if n > 1),
        "stored_unknown": sum(1 for k in keys if k not in tally.attempted),
        "stored_unacknowledged": sum(
            1 for k in keys if k in tally.attempted and k not in acknowledged
        ),
    }
    check["ok"] = (
        check["acknowledged_missing"] == 0
        and check["stored_twice"] == 0
        and check["stored_unknown"] == 0
        and stored == kb_row["n_points"]
    )
    endpoints = {}
    for name, values in sorted(tally.latencies.items()):
        ms = np.asarray(values) * 1000.0
        endpoints[name] = {
            "requests": len(values),
            "per_s": len(values) / elapsed,
            "p50_ms": float(np.percentile(ms, 50)),
            "p95_ms": float(np.percentile(ms, 95)),
            "p99_ms": float(np.percentile(ms, 99)),
            "retries": tally.retries[name],
        }
    return {
        "elapsed_s": elapsed,
        "seeded_points": seeded,
        "points_acknowledged_in_run": len(tally.acknowledged) - seeded,
        "points_per_s": (len(tally.acknowledged) - seeded) / elapsed,
        "suggestions": tally.suggestions,
        "endpoints": endpoints,
        "errors": dict(tally.errors),
        "n_errors": sum(tally.errors.values()),
        "exactly_once": check,
        "surrogates_at_end": states,
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def fresh_database(backend: str, pg_admin_url: str) -> Iterator[str]:
    """A database URL nobody else uses, removed afterwards."""
    if backend == "sqlite":
        with tempfile.TemporaryDirectory(prefix="cpkb-load-") as tmp:
            yield f"sqlite:///{tmp}/kb.sqlite"
        return
    import psycopg

    name = f"cpkb_load_{secrets.token_hex(4)}"
    plain = pg_admin_url.replace("postgresql+psycopg://", "postgresql://")
    with psycopg.connect(plain, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        yield pg_admin_url.rsplit("/", 1)[0] + f"/{name}"
    finally:
        with psycopg.connect(plain, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@contextmanager
def running_server(db_url: str, token: str | None) -> Iterator[str]:
    """`cpkb serve` as a child process on a free loopback port, stopped afterwards.

    Its output goes to a temporary log, printed only if the server dies or misbehaves.
    """
    port = free_port()
    env = {**os.environ, "CPKB_DATABASE_URL": db_url}
    env.pop("CPKB_TOKEN", None)
    if token:
        env["CPKB_TOKEN"] = token
    cmd = [sys.executable, "-m", "cpkb", "serve", "--db", db_url]
    cmd += ["--host", "127.0.0.1", "--port", str(port)]
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(
            cmd, env=env, stdout=log, stderr=subprocess.STDOUT, cwd=REPO, start_new_session=True
        )
        base = f"http://127.0.0.1:{port}"
        try:
            wait_healthy(base, proc, timeout=120.0)
            yield base
        except BaseException:
            log.seek(0)
            sys.stderr.write(log.read()[-4000:].decode(errors="replace"))
            raise
        finally:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            # Anything the server left in its process group (a fit worker) goes with it.
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)


def wait_healthy(base: str, proc: subprocess.Popen, timeout: float) -> None:
    if wait_ready(base, proc, timeout):
        return
    if proc.poll() is not None:
        raise RuntimeError(f"server exited with status {proc.returncode} before it was up")
    raise RuntimeError(f"server not healthy after {timeout:.0f} s")


def print_report(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    table = Table(
        title=f"{result['backend']}, {result['planners']} planners, {result['elapsed_s']:.1f} s"
    )
    for col in ("endpoint", "requests", "req/s", "p50 ms", "p95 ms", "p99 ms", "retries"):
        table.add_column(col, justify="right")
    for name, e in result["endpoints"].items():
        table.add_row(
            name,
            str(e["requests"]),
            f"{e['per_s']:.1f}",
            f"{e['p50_ms']:.1f}",
            f"{e['p95_ms']:.1f}",
            f"{e['p99_ms']:.1f}",
            str(e["retries"]),
        )
    console.print(table)
    check = result["exactly_once"]
    console.print(
        f"points acknowledged in the run: {result['points_acknowledged_in_run']} "
        f"({result['points_per_s']:.1f}/s); errors: {result['n_errors']} {result['errors']}"
    )
    console.print(f"exactly once: {'OK' if check['ok'] else 'FAILED'} {check}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--planners", type=int, default=8, help="concurrent planners (8-32)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of load")
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite")
    parser.add_argument("--pg-admin-url", default=DEFAULT_PG_ADMIN)
    parser.add_argument("--url", help="use this running server instead of starting one")
    parser.add_argument("--token", default=None, help="bearer token for the server")
    parser.add_argument("--seed-points", type=int, default=100, help="points per type first")
    parser.add_argument(
        "--no-suggest", action="store_true", help="post points only (ingest under concurrency)"
    )
    parser.add_argument(
        "--writers", type=int, default=0, help="workers that only post, without pause"
    )
    parser.add_argument("--think", type=float, default=0.0, help="seconds between calls")
    parser.add_argument("--timeout", type=float, default=30.0, help="per-request seconds")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    # A SIGTERM (e.g. from `timeout`) unwinds normally: the server is stopped, the database dropped.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if not 1 <= args.planners <= 256:
        parser.error("--planners must be between 1 and 256")
    if not 0 <= args.writers <= 256:
        parser.error("--writers must be between 0 and 256")
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    mode = ("-postonly" if args.no_suggest else "") + (f"-{args.writers}w" if args.writers else "")
    stem = f"load-{args.backend}-{args.planners}p{mode}-{stamp}"
    if args.url:
        result = asyncio.run(run_load(args.url.rstrip("/"), args, args.token))
    else:
        with (
            fresh_database(args.backend, args.pg_admin_url) as db_url,
            running_server(db_url, args.token) as base,
        ):
            result = asyncio.run(run_load(base, args, args.token))
    result = {
        "backend": args.backend,
        "planners": args.planners,
        "writers": args.writers,
        "duration_s": args.duration,
        "seed_points_per_type": args.seed_points,
        "suggest": not args.no_suggest,
        "command": " ".join(["benchmarks/load.py", *(argv or sys.argv[1:])]),
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "loadavg_1m_after": os.getloadavg()[0],
        },
        "when": stamp,
        **result,
    }
    (args.out / f"{stem}.json").write_text(json.dumps(result, indent=2) + "\n")
    print_report(result)
    print(f"wrote {args.out / f'{stem}.json'}")
    return 0 if result["exactly_once"]["ok"] and result["n_errors"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

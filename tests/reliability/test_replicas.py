"""Two `cpkb serve` replicas on one PostgreSQL act as one service.

Eight planners post failure points (four causal graphs, each planner naming the graphs' nodes
its own way) and ask for suggestions, each through the client given both replicas' URLs, half
of them the other way round. Afterwards every graph is one type, every acknowledged point is
stored once, both replicas serve each type's last fit, and no version of a type was fitted
twice: the replicas' logs name each fit, and their /metrics count the same fits. A suggestion
served by one replica pushes the next one served by the other away. Last, a replica killed in
the middle of a stream of posts loses no acknowledged point, and the survivor fits on.
"""

from __future__ import annotations

import json
import re
import threading
from collections import Counter
from pathlib import Path
from typing import Any

import httpx
import pytest
from killable_server import KillableServer, stored_keys
from service_support import make_graph
from wait_support import wait_until

from client import CpkbClient

pytestmark = [pytest.mark.postgres, pytest.mark.slow]

PLANNERS = 8
ROUNDS = 4
BATCH = 10
GRAPHS = [
    ("Inv-kin", ("box1",)),
    ("Plan-motion", ("box1", "box2")),
    ("Move-Place", ("shelf",)),
    ("Inv-kin", ("box2",)),
]
# Fits run in a thread of each replica: sharing them is the same, and starting a fit process
# would cost each replica seconds of the suite's time.
ENV = {
    "CPKB_SURROGATE__CLAIM_RETRY_S": "0.3",
    "CPKB_SURROGATE__REFRESH_S": "0.2",
    "CPKB_SURROGATE__FIT_PROCESS": "false",
}


def graph(i: int, planner: int) -> dict[str, Any]:
    failure, context = GRAPHS[i]
    return make_graph(failure, context, prefix=f"p{planner}-")


def point(planner: int, n: int) -> dict[str, Any]:
    """A failure point whose label follows the pose, as in a workspace (both classes occur)."""
    pose = [((n * 0.37 + planner * 0.11) % 1.0), ((n * 0.53) % 1.0), ((n * 0.71) % 6.0) - 3.0]
    direction = ("front", "right", "top", "back", "left")[n % 5]
    return {
        "graph": graph(n % len(GRAPHS), planner),
        "x": {"#dir": direction, "#pose": pose},
        "feasible": pose[0] + 0.3 * pose[1] > 0.6 and direction != "top",
        "key": f"planner{planner}-{n}",
        "source": {"task": "replicas", "run": f"planner{planner}", "rollout": n},
    }


def start_replicas(postgres_url: str, tmp_path: Path) -> list[KillableServer]:
    replicas = []
    for name in ("a", "b"):
        log_dir = tmp_path / name
        log_dir.mkdir()
        env = ENV | {"CPKB_REPLICA_NAME": f"replica-{name}"}
        replicas.append(KillableServer(postgres_url, log_dir, env=env))
    threads = [threading.Thread(target=r.start) for r in replicas]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in replicas:
        assert r.proc is not None and r.proc.poll() is None, r.log_tail()
    return replicas


def urls(replicas: list[KillableServer], planner: int) -> str:
    ordered = replicas if planner % 2 == 0 else replicas[::-1]
    return ",".join(r.url for r in ordered)


def fit_records(replicas: list[KillableServer]) -> list[dict[str, Any]]:
    """The `fitted ... version N` records of both replicas' JSON logs."""
    records = []
    for r in replicas:
        for line in (r.log_dir / f"server-{r.starts}.log").read_text(errors="replace").splitlines():
            if line.startswith("{") and '"fitted ' in line:
                records.append(json.loads(line))
    return records


def metric(url: str, name: str) -> float:
    text = httpx.get(f"{url}/metrics", timeout=30).raise_for_status().text
    found = re.search(rf"^{re.escape(name)} ([0-9.e+]+)$", text, re.MULTILINE)
    return float(found.group(1)) if found else 0.0


def planner_run(planner: int, url: str, seen: list[set[str]], errors: list[str]) -> None:
    """Post `ROUNDS` batches; after each, ask for a suggestion constrained by a posted type."""
    try:
        with CpkbClient(url, timeout=60) as kb:
            for round_ in range(ROUNDS):
                batch = [point(planner, round_ * BATCH + j) for j in range(BATCH)]
                results = kb.post_points("default", batch)
                for j, result in enumerate(results):
                    seen[(round_ * BATCH + j) % len(GRAPHS)].add(result.type_id)
                nodes = batch[0]["graph"]["nodes"]
                domains = {n["label"]: n["domain"] for n in nodes if "domain" in n}
                bind = {"#dir": "d", "#pose": "p"}
                kb.suggest(
                    "default",
                    {
                        "space": {"d": domains["#dir"], "p": domains["#pose"]},
                        "constraints": [{"type_id": results[0].type_id, "bind": bind}],
                    },
                )
    except Exception as exc:  # reported by the test, with the planner's number
        errors.append(f"planner {planner}: {type(exc).__name__}: {exc}")


def settled(replicas: list[KillableServer], type_ids: list[str]) -> bool:
    """Each replica serves every type from a fit of all its stored points."""
    counts = {t["type_id"]: t["n_points"] for t in _types(replicas[-1].url)}
    for r in replicas:
        with CpkbClient(r.url) as kb:
            models = kb.models("default", type_ids).models
        if any(m.n_fitted != counts[m.type_id] for m in models) or len(models) != len(type_ids):
            return False
    return True


def _types(url: str) -> list[dict[str, Any]]:
    return httpx.get(f"{url}/v1/kbs/default/types", timeout=30).raise_for_status().json()


class Poster(threading.Thread):
    """Posts keyed batches through the failing-over client; records what was acknowledged."""

    def __init__(self, number: int, url: str, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.number, self.url, self.stop = number, url, stop
        self.acknowledged: list[str] = []
        self.error: str | None = None

    def run(self) -> None:
        try:
            with CpkbClient(self.url, timeout=30, reconnect_for=60) as kb:
                n = 0
                while not self.stop.is_set():
                    batch = [point(self.number, n + j) for j in range(5)]
                    kb.post_points("default", batch)
                    self.acknowledged.extend(p["key"] for p in batch)
                    n += 5
        except Exception as exc:  # reported by the test
            self.error = f"{type(exc).__name__}: {exc}"


def test_two_replicas_act_as_one_service(postgres_url: str, tmp_path: Path) -> None:
    replicas = start_replicas(postgres_url, tmp_path)
    try:
        seen: list[set[str]] = [set() for _ in GRAPHS]
        errors: list[str] = []
        planners = [
            threading.Thread(target=planner_run, args=(i, urls(replicas, i), seen, errors))
            for i in range(PLANNERS)
        ]
        for t in planners:
            t.start()
        for t in planners:
            t.join()
        assert errors == []

        # One type per graph, whichever replica created it and however its nodes are named.
        assert all(len(ids) == 1 for ids in seen), seen
        type_ids = [next(iter(ids)) for ids in seen]
        assert sorted(t["type_id"] for t in _types(replicas[1].url)) == sorted(type_ids)
        # Every point once.
        keys = stored_keys(replicas[0].url)
        assert len(keys) == PLANNERS * ROUNDS * BATCH and set(keys.values()) == {1}

        wait_until(
            lambda: settled(replicas, type_ids),
            interval=0.5,
            what="both replicas serving a fit of every stored point",
        )
        records = fit_records(replicas)
        versions = Counter((r["type_id"], r["version"]) for r in records)
        assert versions and max(versions.values()) == 1, versions
        fitted = [metric(r.url, 'cpkb_surrogate_fits_total{outcome="ok"}') for r in replicas]
        adopted = [metric(r.url, "cpkb_surrogate_fits_adopted_total") for r in replicas]
        assert sum(fitted) == len(records)
        assert sum(adopted) > 0  # a replica loaded the other's fits instead of fitting them

        # A suggestion served by one replica keeps the other's next one away from it.
        request = {
            "space": {"p": {"kind": "continuous", "low": [0.0], "high": [1.0]}},
            "constraints": [],
            "seed": 7,
        }
        first, second = (
            httpx.post(f"{r.url}/v1/kbs/default/suggest", json=request, timeout=60)
            .raise_for_status()
            .json()
            for r in replicas
        )
        assert second["n_pending"] == first["n_pending"] + 1
        assert second["x"] != first["x"]

        # A replica killed mid-request: posters go on through the other, nothing is lost.
        stop = threading.Event()
        posters = [Poster(100 + i, urls(replicas, i), stop) for i in range(4)]
        for p in posters:
            p.start()
        wait_until(lambda: sum(len(p.acknowledged) for p in posters) >= 120, what="120 points")
        replicas[0].kill()  # SIGKILL, with posts (and perhaps a fit and its claim) in flight
        after = sum(len(p.acknowledged) for p in posters)
        wait_until(
            lambda: sum(len(p.acknowledged) for p in posters) >= after + 120,
            what="120 more points through the surviving replica",
        )
        stop.set()
        for p in posters:
            p.join(timeout=120)
        assert [p.error for p in posters] == [None] * len(posters)
        acknowledged = {k for p in posters for k in p.acknowledged}
        keys = stored_keys(replicas[1].url)
        assert acknowledged <= set(keys)
        assert set(keys.values()) == {1}
        assert len(keys) == PLANNERS * ROUNDS * BATCH + len(acknowledged)
        # The dead replica's claims died with it: the survivor fits every type to the end.
        wait_until(lambda: settled(replicas[1:], type_ids), interval=0.5, what="the last fits")
    finally:
        for r in replicas:
            r.stop()

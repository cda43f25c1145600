"""8 planner processes post 500 points each through the client to one server.

Every process posts its own 500 keyed points in batches of 25 (three types, so that the first
batches race to create the same types), and also re-posts the first batch of its neighbour,
racing the neighbour's own post of the same keys. Client retries are off: any 5xx or
"database is locked" would fail the run instead of being retried away.
"""

from __future__ import annotations

import multiprocessing
from typing import Any

import pytest
from service_support import LiveServer, make_graph, make_point

from client import CpkbClient

WORKERS = 8
PER_WORKER = 500
BATCH = 25
GRAPHS = [make_graph(failure=f) for f in ("Inv-kin", "Plan-motion", "Move-Place")]


def worker_points(worker: int) -> list[dict[str, Any]]:
    return [
        make_point(i, graph=GRAPHS[i % 3], key=f"w{worker}-p{i}", worker=f"w{worker}", rollout=i)
        for i in range(PER_WORKER)
    ]


def run_worker(url: str, kb: str, worker: int) -> dict[str, int]:
    """Posts this worker's points, then its neighbour's first batch; key -> point id."""
    points = worker_points(worker)
    neighbour = worker_points((worker + 1) % WORKERS)[:BATCH]
    ids: dict[str, int] = {}
    with CpkbClient(url, retries=0, timeout=120) as client:
        for batch in [points[:BATCH], neighbour, *_batches(points[BATCH:])]:
            for point, result in zip(batch, client.post_points(kb, batch), strict=True):
                ids[point["key"]] = result.point_id
    return ids


def _batches(points: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    return [points[i : i + BATCH] for i in range(0, len(points), BATCH)]


@pytest.mark.slow
def test_eight_processes_store_every_point_exactly_once(
    shared_server: LiveServer, kb_client: tuple[CpkbClient, str]
) -> None:
    client, kb = kb_client
    context = multiprocessing.get_context("spawn")
    with context.Pool(WORKERS) as pool:
        answers = pool.starmap(run_worker, [(shared_server.url, kb, w) for w in range(WORKERS)])

    merged: dict[str, int] = {}
    for answer in answers:
        for key, point_id in answer.items():
            assert merged.setdefault(key, point_id) == point_id, f"{key} got two point ids"
    assert len(merged) == WORKERS * PER_WORKER

    types = client.list_types(kb)
    assert len(types) == 3
    stored = [p for t in types for p in client.iter_points(kb, t.type_id)]
    assert len(stored) == WORKERS * PER_WORKER
    assert len({p.key for p in stored}) == len(stored)
    assert len({p.point_id for p in stored}) == len(stored)
    assert {p.key: p.point_id for p in stored} == merged
    assert client.get_kb(kb).n_points == WORKERS * PER_WORKER
    assert sum(t.n_points for t in types) == WORKERS * PER_WORKER
    log = shared_server.log.read_text(errors="replace")
    assert "database is locked" not in log
    assert '"status": 201' in log  # the (JSON) access log is there to be checked
    assert " 500 " not in log and " 503 " not in log

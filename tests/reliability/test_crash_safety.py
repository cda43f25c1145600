"""SIGKILL the server in the middle of a stream of posts, restart it, and account for every point.

Posters keep posting batches with idempotency keys; a batch whose answer is lost (the server died
with it in flight, before or after its commit) is re-sent with the same keys until acknowledged.
Beside them the project's client posts a stream with its own keys and retries. Afterwards every
acknowledged point is stored exactly once and the database opens cleanly.
"""

from __future__ import annotations

import sqlite3
import threading
import time
from pathlib import Path

import httpx
import pytest
from killable_server import KillableServer, kb_point_count, stored_keys

from client import CpkbClient

BOX = {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]}
GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Move-Place"},
        {"id": "p", "role": "decision", "label": "#pose", "domain": BOX},
        {"id": "c", "role": "context", "label": "box1"},
    ],
    "edges": [
        {"source": "p", "target": "f", "label": "feeds"},
        {"source": "c", "target": "f", "label": "collides"},
    ],
}
BATCH = 5


def point(i: int, key: str | None = None) -> dict:
    x = [(i * 0.137) % 1.0, (i * 0.311) % 1.0, 0.5]
    body = {"graph": GRAPH, "x": {"#pose": x}, "feasible": i % 3 == 0}
    return body | ({"key": key} if key else {})


class Poster(threading.Thread):
    """Posts numbered batches; re-sends a batch with the same keys until it is acknowledged."""

    def __init__(self, url: str, name: str, stop: threading.Event, deadline: float) -> None:
        super().__init__(daemon=True)
        self.url, self.worker, self.stop, self.deadline = url, name, stop, deadline
        self.acknowledged: list[str] = []
        self.lost_answers = 0
        self.failure: str | None = None

    def run(self) -> None:
        seq = 0
        with httpx.Client(base_url=self.url, timeout=10) as http:
            while not self.stop.is_set():
                keys = [f"{self.worker}-{seq}-{j}" for j in range(BATCH)]
                body = {"points": [point(seq * BATCH + j, k) for j, k in enumerate(keys)]}
                attempt = 0
                while True:
                    if time.monotonic() > self.deadline:
                        self.failure = f"batch {seq} never acknowledged"
                        return
                    try:
                        response = http.post("/v1/kbs/default/points", json=body)
                    except httpx.TransportError:
                        self.lost_answers += 1
                    else:
                        if response.status_code == 201:
                            break
                        if response.status_code < 500:
                            self.failure = f"{response.status_code}: {response.text[:300]}"
                            return
                        self.lost_answers += 1
                    attempt += 1
                    time.sleep(min(0.5, 0.02 * 2**attempt))
                self.acknowledged.extend(keys)
                seq += 1

    @staticmethod
    def total(posters: list[Poster]) -> int:
        return sum(len(p.acknowledged) for p in posters)


def wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


class ClientStream(threading.Thread):
    """A planner-like stream through the project's client with its defaults: one point per
    call, keyed by the client itself, retried by the client across the restart."""

    def __init__(self, url: str, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.url, self.stop = url, stop
        self.results: list = []
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            with CpkbClient(self.url) as client:
                i = 0
                while not self.stop.is_set():
                    self.results.extend(client.post_points("default", [point(10_000 + i)]))
                    i += 1
        except BaseException as exc:
            self.error = exc


@pytest.mark.slow
def test_sigkill_mid_stream_loses_nothing_and_stores_nothing_twice(
    sqlite_url: str, tmp_path: Path
) -> None:
    server = KillableServer(sqlite_url, tmp_path, env={"CPKB_SURROGATE__ENABLED": "false"})
    server.start()
    stop = threading.Event()
    posters = [Poster(server.url, f"w{i}", stop, time.monotonic() + 480) for i in range(3)]
    stream = ClientStream(server.url, stop)
    try:
        for thread in (*posters, stream):
            thread.start()
        wait_for(lambda: Poster.total(posters) >= 100, 120, "100 points before the kill")
        server.kill()
        at_kill, stream_at_kill = Poster.total(posters), len(stream.results)
        time.sleep(0.3)
        server.start()
        wait_for(
            lambda: (
                Poster.total(posters) >= at_kill + 100 and len(stream.results) > stream_at_kill + 5
            ),
            240,
            "points from every poster after the restart",
        )
    finally:
        stop.set()
        for thread in (*posters, stream):
            thread.join(timeout=60)
    assert all(p.failure is None for p in posters), [p.failure for p in posters]
    assert sum(p.lost_answers for p in posters) > 0, "the kill interrupted no request"
    assert stream.error is None, f"the client gave up across the restart: {stream.error!r}"

    acknowledged = [k for p in posters for k in p.acknowledged]
    keys = stored_keys(server.url)
    missing = [k for k in acknowledged if keys[k] == 0]
    twice = {k: n for k, n in keys.items() if n > 1}
    assert not missing, f"{len(missing)} acknowledged points lost, e.g. {missing[:5]}"
    assert not twice, f"stored more than once: {list(twice.items())[:5]}"
    # Nothing but acknowledged points: a lost answer was always re-sent until acknowledged,
    # and every point the client acknowledged is stored once under the key it chose.
    client_keys = set(keys) - set(acknowledged)
    assert len(client_keys) == len(stream.results) == len({r.point_id for r in stream.results})
    assert kb_point_count(server.url) == len(acknowledged) + len(stream.results)

    # The restart above opened the killed database; it must also pass its own checks.
    server.stop()
    with sqlite3.connect(sqlite_url.removeprefix("sqlite:///")) as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone() == ("ok",)

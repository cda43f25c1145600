"""A replica frozen mid-transaction (SIGSTOP, as a paused VM) does not stop the other.

Two `cpkb serve` replicas on one PostgreSQL take posts of the same four types, so that each
post locks type rows the other replica's posts need too. After a baseline with both running,
replica A is stopped while it holds a write transaction open (checked in pg_stat_activity; the
stop is retried until it lands there). Replica B, with the default lock and idle-transaction
bounds, must acknowledge a post begun after the freeze within 10 s and keep at least 80 % of
its baseline rate over the minute after; its /healthz answers throughout. Last, A is resumed:
every acknowledged point is stored exactly once.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import httpx
import psycopg
import pytest
from killable_server import KillableServer, stored_keys
from sqlalchemy.engine import make_url
from test_replicas import point
from wait_support import wait_until

from client import CpkbClient

pytestmark = [pytest.mark.postgres, pytest.mark.slow]

# Posts only: fits would share the two cores the rates are measured on.
ENV = {"CPKB_SURROGATE__ENABLED": "false"}
BASELINE_S = 20.0
FROZEN_S = 60.0
RECOVERY_S = 10.0
KEPT_RATE = 0.8


class Poster(threading.Thread):
    """Posts keyed batches of 5 to one replica until stopped; keeps (start, end) of each
    acknowledged post and the keys acknowledged."""

    def __init__(self, number: int, url: str, stop: threading.Event) -> None:
        super().__init__(daemon=True)
        self.number, self.url, self.stop = number, url, stop
        self.posts: list[tuple[float, float]] = []
        self.acknowledged: list[str] = []
        self.error: str | None = None

    def run(self) -> None:
        try:
            with CpkbClient(self.url, timeout=300, retries=1000, max_backoff=1.0) as kb:
                n = 0
                while not self.stop.is_set():
                    batch = [point(self.number, n + j) for j in range(5)]
                    start = time.monotonic()
                    kb.post_points("default", batch)
                    self.posts.append((start, time.monotonic()))
                    self.acknowledged.extend(p["key"] for p in batch)
                    n += 5
        except Exception as exc:  # reported by the test
            self.error = f"{type(exc).__name__}: {exc}"


def holds_a_write_transaction(db_url: str) -> bool:
    """Some session has sat idle inside a transaction that wrote or locked rows: the frozen
    replica's (a running replica's sessions are never idle inside a transaction this long)."""
    dsn = make_url(db_url).set(drivername="postgresql").render_as_string(hide_password=False)
    query = (
        "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() "
        "AND state = 'idle in transaction' AND backend_xid IS NOT NULL "
        "AND now() - state_change > interval '500 milliseconds'"
    )
    with psycopg.connect(dsn, autocommit=True) as conn:
        return conn.execute(query).fetchone()[0] > 0


def freeze_mid_transaction(replica: KillableServer, db_url: str, tries: int = 100) -> float:
    """SIGSTOP the replica at a moment it holds a write transaction open; the freeze's time."""
    assert replica.proc is not None
    for _ in range(tries):
        os.kill(replica.proc.pid, signal.SIGSTOP)
        frozen_at = time.monotonic()
        time.sleep(0.7)
        if holds_a_write_transaction(db_url):
            return frozen_at
        os.kill(replica.proc.pid, signal.SIGCONT)
        time.sleep(0.2)
    raise AssertionError(f"replica never stopped inside a write transaction in {tries} tries")


def acks_between(posters: list[Poster], start: float, end: float) -> int:
    return sum(start <= done < end for p in posters for _, done in p.posts)


def test_a_frozen_replica_does_not_stop_the_other(postgres_url: str, tmp_path: Path) -> None:
    replicas = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        replicas.append(
            KillableServer(postgres_url, tmp_path / name, env=ENV | {"CPKB_REPLICA_NAME": name})
        )
    for r in replicas:
        r.start()
    a, b = replicas
    stop = threading.Event()
    on_a = [Poster(i, a.url, stop) for i in range(4)]
    on_b = [Poster(10 + i, b.url, stop) for i in range(4)]
    try:
        for p in on_a + on_b:
            p.start()
        wait_until(lambda: all(p.posts for p in on_a + on_b), what="every poster acknowledged")
        base_start = time.monotonic()
        time.sleep(BASELINE_S)
        baseline = acks_between(on_b, base_start, base_start + BASELINE_S) / BASELINE_S

        frozen_at = freeze_mid_transaction(a, postgres_url)
        health = httpx.get(f"{b.url}/healthz", timeout=60)
        wait_until(
            lambda: time.monotonic() > frozen_at + FROZEN_S,
            timeout=FROZEN_S + 30,
            interval=1.0,
            what="the frozen minute",
        )
        begun_after = sorted(done for p in on_b for start, done in p.posts if start > frozen_at)
        frozen_rate = acks_between(on_b, frozen_at, frozen_at + FROZEN_S) / FROZEN_S
    finally:
        if a.proc is not None and a.proc.poll() is None:
            os.kill(a.proc.pid, signal.SIGCONT)
    try:
        stop.set()
        for p in on_a + on_b:
            p.join(timeout=300)
        assert [p.error for p in on_a + on_b] == [None] * 8
        keys = stored_keys(b.url)
    finally:
        for r in replicas:
            r.stop()

    recovery = begun_after[0] - frozen_at if begun_after else float("inf")
    print(  # the figures, for `pytest -s`
        f"baseline {baseline:.2f} posts/s; frozen minute {frozen_rate:.2f} posts/s; "
        f"first post begun after the freeze acknowledged after {recovery:.1f} s"
    )
    assert health.status_code == 200
    assert begun_after, "replica B acknowledged no post begun after the freeze"
    assert recovery <= RECOVERY_S, f"B's first acknowledgement came {recovery:.1f} s after"
    assert frozen_rate >= KEPT_RATE * baseline, (frozen_rate, baseline)
    acknowledged = {k for p in on_a + on_b for k in p.acknowledged}
    assert acknowledged <= set(keys) and set(keys.values()) == {1}

"""On PostgreSQL a post waits a bounded time for a lock another session holds (a replica frozen
mid-transaction holds its type rows): it answers 503 with Retry-After, the client retries until
the lock is gone, and the health check answers while every worker waits on the lock."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import httpx
import psycopg
import pytest
from service_support import make_point, run_live_server
from sqlalchemy.engine import make_url
from wait_support import wait_until

from client import CpkbClient

pytestmark = pytest.mark.postgres

POINTS = "/v1/kbs/default/points"


def dsn(db_url: str) -> str:
    return make_url(db_url).set(drivername="postgresql").render_as_string(hide_password=False)


def sessions_waiting_on_a_lock(db_url: str) -> int:
    with psycopg.connect(dsn(db_url), autocommit=True) as conn:
        query = "SELECT count(*) FROM pg_stat_activity WHERE wait_event_type = 'Lock'"
        return conn.execute(query).fetchone()[0]


class TypeLock:
    """Another session's transaction holding every type row (`FOR UPDATE`), as a replica
    stopped mid-post does. Ended by PostgreSQL after `safety_s` if the test never releases
    it, so that a service that waits for ever fails the test instead of hanging it."""

    def __init__(self, db_url: str, safety_s: int = 40) -> None:
        self.conn = psycopg.connect(dsn(db_url))
        self.conn.execute(f"SET idle_in_transaction_session_timeout = '{safety_s}s'")
        self.conn.execute("SELECT id FROM cp_types FOR UPDATE").fetchall()

    def release(self) -> None:
        if not self.conn.closed:
            self.conn.rollback()
            self.conn.close()


@pytest.fixture
def server(postgres_url: str, tmp_path: Path) -> Iterator[str]:
    env = {"CPKB_PG_LOCK_TIMEOUT_MS": "500", "CPKB_SURROGATE__ENABLED": "false"}
    with run_live_server(postgres_url, tmp_path / "server.log", env=env) as live:
        httpx.post(live.url + POINTS, json={"points": [make_point(0)]}).raise_for_status()
        yield live.url


def test_a_post_behind_a_held_lock_answers_503_and_the_client_retries(
    server: str, postgres_url: str
) -> None:
    lock = TypeLock(postgres_url)
    try:
        refused = httpx.post(server + POINTS, json={"points": [make_point(1)]}, timeout=120)
        assert refused.status_code == 503, refused.text
        assert refused.headers["Retry-After"].isdigit()
        assert "lock" in refused.json()["detail"]

        acknowledged: list[int] = []
        with CpkbClient(server, retries=100, max_backoff=0.5) as kb:
            poster = threading.Thread(
                target=lambda: acknowledged.extend(
                    r.point_id for r in kb.post_points("default", [make_point(2)])
                )
            )
            poster.start()
            poster.join(timeout=3)
            assert poster.is_alive() and not acknowledged  # still retrying behind the lock
            lock.release()
            poster.join(timeout=120)
        assert len(acknowledged) == 1
    finally:
        lock.release()


def test_health_answers_while_every_worker_waits_on_a_lock(
    postgres_url: str, tmp_path: Path
) -> None:
    # Lock waits long enough that the posts below still wait when health is asked.
    env = {"CPKB_PG_LOCK_TIMEOUT_MS": "60000", "CPKB_SURROGATE__ENABLED": "false"}
    with run_live_server(postgres_url, tmp_path / "server.log", env=env) as live:
        httpx.post(live.url + POINTS, json={"points": [make_point(0)]}).raise_for_status()
        lock = TypeLock(postgres_url)
        answers: list[int] = []

        def post(i: int) -> None:
            response = httpx.post(live.url + POINTS, json={"points": [make_point(i)]}, timeout=120)
            answers.append(response.status_code)

        # More posts than the pool has connections and the server has worker threads.
        posts = [threading.Thread(target=post, args=(i,)) for i in range(1, 49)]
        try:
            for t in posts:
                t.start()
            # Most of the pool's 30 connections (10, and 20 of overflow) behind the lock.
            wait_until(
                lambda: sessions_waiting_on_a_lock(postgres_url) >= 25,
                what="25 posts waiting on the lock",
            )
            health = httpx.get(live.url + "/healthz", timeout=120)
            waiting, answered = sum(t.is_alive() for t in posts), len(answers)
            head = httpx.head(live.url + "/healthz", timeout=120)
        finally:
            lock.release()
            for t in posts:
                t.join(timeout=120)
        assert health.status_code == 200 and head.status_code == 200
        assert waiting == len(posts) and answered == 0, answers  # ...answered before any post
        assert sorted(set(answers)) == [201]

"""A write racing the DELETE of its knowledge base is a 404, as it would be a moment later.

On PostgreSQL the write can look the knowledge base up before the DELETE commits and insert
after: the foreign key refuses it, which is the knowledge base being gone, not a conflict.
(SQLite serialises writers, so there the write starts after the DELETE and finds nothing.)
"""

from __future__ import annotations

import threading
import time
from typing import Any

import psycopg
import pytest
from fastapi.testclient import TestClient
from service_support import make_point
from sqlalchemy.engine import make_url

from server.app import create_app
from server.hooks import ServiceHooks
from server.settings import Settings

WAIT_S = 120  # a bound for a loaded machine, not a deadline the test races


def libpq_dsn(url: str) -> str:
    return make_url(url).set(drivername="postgresql").render_as_string(hide_password=False)


def wait_for_a_blocked_backend(dsn: str) -> None:
    """Until another session of this database waits for a row lock (the write's FK check)."""
    deadline = time.monotonic() + WAIT_S
    with psycopg.connect(dsn, autocommit=True) as watcher:
        while True:
            waiting = watcher.execute(
                "SELECT count(*) FROM pg_stat_activity "
                "WHERE datname = current_database() AND wait_event_type = 'Lock'"
            ).fetchone()
            if waiting and waiting[0] > 0:
                return
            assert time.monotonic() < deadline, "the write never reached the deleted row"
            time.sleep(0.05)


@pytest.mark.postgres
def test_a_write_racing_a_delete_is_404(postgres_url: str) -> None:
    app = create_app(Settings(database_url=postgres_url))
    app.state.hooks.__dict__.update(ServiceHooks().__dict__)
    dsn = libpq_dsn(postgres_url)
    with TestClient(app) as client:
        assert client.post("/v1/kbs", json={"name": "race"}).status_code == 201
        answers: list[Any] = []
        with psycopg.connect(dsn) as deleting:
            deleting.execute("DELETE FROM knowledge_bases WHERE name = 'race'")
            writer = threading.Thread(
                target=lambda: answers.append(
                    client.post("/v1/kbs/race/points", json={"points": [make_point(1)]})
                )
            )
            writer.start()
            wait_for_a_blocked_backend(dsn)
            deleting.commit()
        writer.join(timeout=WAIT_S)
        (answer,) = answers
        assert answer.status_code == 404, answer.text
        assert "deleted" in answer.json()["detail"]
        assert client.get("/v1/kbs/race").status_code == 404

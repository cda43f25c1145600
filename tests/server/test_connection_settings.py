"""The database settings reach every connection the service opens: SQLite's `synchronous`
(read back with PRAGMA), PostgreSQL's lock and idle-transaction bounds (read back with SHOW);
and the health probe answers HEAD as well as GET."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from server.app import create_app
from server.settings import Settings

SYNCHRONOUS = {1: "NORMAL", 2: "FULL"}  # what PRAGMA synchronous answers


def running(db_url: str, env: dict[str, str], monkeypatch: pytest.MonkeyPatch) -> TestClient:
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    return TestClient(create_app(Settings(database_url=db_url, surrogate_enabled=False)))


def read_back(client: TestClient, query: str, *, write: bool = False) -> Any:
    with client.app.state.store.transaction(write=write) as session:
        return session.execute(text(query)).scalar()


@pytest.mark.parametrize("chosen", [None, "FULL", "NORMAL"])
def test_sqlite_synchronous_is_the_setting(
    sqlite_url: str, chosen: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    env = {} if chosen is None else {"CPKB_SQLITE_SYNCHRONOUS": chosen}
    with running(sqlite_url, env, monkeypatch) as client:
        for write in (False, True):
            value = read_back(client, "PRAGMA synchronous", write=write)
            assert SYNCHRONOUS[value] == (chosen or "NORMAL")
        assert read_back(client, "PRAGMA journal_mode") == "wal"


def test_a_synchronous_mode_sqlite_does_not_know_is_refused(sqlite_url: str) -> None:
    with pytest.raises(ValueError, match="sqlite_synchronous"):
        Settings(database_url=sqlite_url, sqlite_synchronous="SOMETIMES")


@pytest.mark.postgres
def test_postgres_sessions_bound_lock_waits_and_idle_transactions(
    postgres_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    env = {
        "CPKB_PG_LOCK_TIMEOUT_MS": "1500",
        "CPKB_PG_IDLE_IN_TRANSACTION_TIMEOUT_MS": "4000",
        "CPKB_REPLICA_NAME": "replica-a",
    }
    with running(postgres_url, env, monkeypatch) as client:
        for write in (False, True):
            assert read_back(client, "SHOW lock_timeout", write=write) == "1500ms"
            idle = read_back(client, "SHOW idle_in_transaction_session_timeout", write=write)
            assert idle == "4s"
            assert read_back(client, "SHOW application_name") == "replica-a"


@pytest.mark.postgres
def test_postgres_defaults_bound_lock_waits(postgres_url: str) -> None:
    with TestClient(create_app(Settings(database_url=postgres_url, surrogate_enabled=False))) as c:
        assert read_back(c, "SHOW lock_timeout") not in ("0", "0ms")
        assert read_back(c, "SHOW idle_in_transaction_session_timeout") not in ("0", "0ms")


@pytest.fixture
def service(db_url: str) -> Iterator[TestClient]:
    with TestClient(create_app(Settings(database_url=db_url, surrogate_enabled=False))) as c:
        yield c


def test_healthz_answers_head_as_get(service: TestClient) -> None:
    head = service.head("/healthz")
    assert head.status_code == 200 and head.content == b""
    assert service.get("/healthz").json()["status"] == "ok"

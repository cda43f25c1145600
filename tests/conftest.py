"""Shared fixtures for tests that need the knowledge-base service.

- `sqlite_url`: a fresh SQLite file URL per test.
- `postgres_url`: a fresh PostgreSQL database per test (CPKB_TEST_POSTGRES_URL points at the
  server, default postgresql+psycopg://postgres@127.0.0.1:5432/test), dropped afterwards;
  skipped with the reason when the server cannot be reached.
- `db_url`: parametrised over both ("sqlite", "postgres"): a test written once runs on each.
- `app_db_url`: `db_url`, its SQLite file a copy of one brought to head once per session
  (`migrated_sqlite`), so that an in-process app does not migrate an empty file anew; the
  migration tests, `sqlite_url` and the live servers still start from an empty one.
- `app_client`: a TestClient over `create_app` on `app_db_url`.
- `core_client`: the same app with its extension hooks (server.hooks: the surrogate engine)
  removed before start: the core API alone, without fits that slow every test's teardown.
- `live_server`: `cpkb serve` in a subprocess on a free loopback port, on `db_url`; yields
  a `LiveServer(url, db_url, log)` (`log`: the server's output file).
- `fresh_postgres_database(reason)` and `run_live_server(db_url, log)`: the same as context
  managers, for fixtures of a wider scope.
- `kb_service`: one real `cpkb serve` on a fresh SQLite file for the whole session (it takes
  seconds to start), for tests that use a knowledge base of their own on it; `live_kb`: a
  fresh knowledge base on it per test (`LiveKb(url, name)`).
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from service_support import (
    LiveServer,
    at_head,
    fresh_postgres_database,
    postgres_admin_url,
    run_live_server,
)


def pytest_collection_finish(session: pytest.Session) -> None:
    """Fail the run at once if importing a test module started a thread.

    Such a thread runs beside the assertion rewriting of every later module, and CPython 3.11's
    `ast.parse` beside a thread that parses fails at random ("AST constructor recursion depth
    mismatch", python/cpython#106905): start servers and apps in fixtures, never at import.
    """
    started = [t.name for t in threading.enumerate() if t is not threading.main_thread()]
    if started:
        raise pytest.UsageError(f"collecting the tests started threads {started}: use fixtures")


@pytest.fixture(scope="session")
def postgres_unreachable_reason() -> str | None:
    """None if reachable, else the reason (checked once per session)."""
    import psycopg
    from sqlalchemy.engine import make_url

    url = make_url(postgres_admin_url())
    try:
        with psycopg.connect(
            url.set(drivername="postgresql").render_as_string(hide_password=False),
            connect_timeout=3,
        ):
            return None
    except psycopg.Error as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return f"PostgreSQL at {url.render_as_string()} is not reachable: {first}"


@pytest.fixture
def postgres_url(postgres_unreachable_reason: str | None) -> Iterator[str]:
    with fresh_postgres_database(postgres_unreachable_reason) as url:
        yield url


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'kb.sqlite'}"


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def db_url(request: pytest.FixtureRequest) -> str:
    return request.getfixturevalue(f"{request.param}_url")


@pytest.fixture(scope="session")
def migrated_sqlite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from server.db import Store
    from server.schema import prepare_database

    path: Path = tmp_path_factory.mktemp("template") / "kb.sqlite"
    store = Store.from_url(f"sqlite:///{path}")
    try:
        prepare_database(store)
    finally:
        store.dispose()
    return path


@pytest.fixture
def app_db_url(db_url: str, migrated_sqlite: Path) -> str:
    return at_head(db_url, migrated_sqlite)


@pytest.fixture
def app_client(app_db_url: str) -> Iterator[object]:
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.settings import Settings

    with TestClient(create_app(Settings(database_url=app_db_url))) as client:
        yield client


@pytest.fixture
def core_client(app_db_url: str) -> Iterator[object]:
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.hooks import ServiceHooks
    from server.settings import Settings

    app = create_app(Settings(database_url=app_db_url))
    app.state.hooks.__dict__.update(ServiceHooks().__dict__)
    with TestClient(app) as client:
        yield client


@pytest.fixture
def live_server(db_url: str, tmp_path: Path) -> Iterator[LiveServer]:
    with run_live_server(db_url, tmp_path / "server.log") as server:
        yield server


@dataclass(frozen=True)
class LiveKb:
    url: str
    name: str


@pytest.fixture(scope="session")
def kb_service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    from cpkb.embedded import embedded_service

    db: Path = tmp_path_factory.mktemp("kb") / "kb.sqlite"
    with embedded_service(f"sqlite:///{db}") as url:
        yield url


@pytest.fixture
def live_kb(kb_service: str) -> LiveKb:
    from client import CpkbClient

    name = f"t-{uuid.uuid4().hex[:12]}"
    with CpkbClient(kb_service) as client:
        client.create_kb(name)
    return LiveKb(kb_service, name)

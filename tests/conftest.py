"""Shared fixtures for tests that need the knowledge-base service.

- `sqlite_url`: a fresh SQLite file URL per test.
- `postgres_url`: a fresh PostgreSQL database per test (CPKB_TEST_POSTGRES_URL points at the
  server, default postgresql+psycopg://postgres@127.0.0.1:5432/test), dropped afterwards;
  skipped with the reason when the server cannot be reached.
- `db_url`: parametrised over both ("sqlite", "postgres"): a test written once runs on each.
- `app_client`: a TestClient over `create_app` on `db_url`.
- `live_server`: `cpkb serve` in a subprocess on a free loopback port, on `db_url`; yields
  a `LiveServer(url, db_url)`.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

DEFAULT_TEST_POSTGRES_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


def _postgres_admin_url() -> str:
    return os.environ.get("CPKB_TEST_POSTGRES_URL", DEFAULT_TEST_POSTGRES_URL)


@pytest.fixture(scope="session")
def _postgres_reachable() -> str | None:
    """None if reachable, else the reason (checked once per session)."""
    import psycopg
    from sqlalchemy.engine import make_url

    url = make_url(_postgres_admin_url())
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
def postgres_url(_postgres_reachable: str | None) -> Iterator[str]:
    if _postgres_reachable is not None:
        pytest.skip(_postgres_reachable)
    import psycopg
    from sqlalchemy.engine import make_url

    admin = make_url(_postgres_admin_url())
    admin_dsn = admin.set(drivername="postgresql").render_as_string(hide_password=False)
    name = f"cpkb_t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(admin_dsn, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        yield admin.set(database=name).render_as_string(hide_password=False)
    finally:
        with psycopg.connect(admin_dsn, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@pytest.fixture
def sqlite_url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'kb.sqlite'}"


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def db_url(request: pytest.FixtureRequest) -> str:
    return request.getfixturevalue(f"{request.param}_url")


@pytest.fixture
def app_client(db_url: str) -> Iterator[object]:
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.settings import Settings

    with TestClient(create_app(Settings(database_url=db_url))) as client:
        yield client


@dataclass(frozen=True)
class LiveServer:
    url: str
    db_url: str


@pytest.fixture
def live_server(db_url: str) -> Iterator[LiveServer]:
    from cpkb.embedded import embedded_service

    with embedded_service(db_url) as url:
        yield LiveServer(url=url, db_url=db_url)

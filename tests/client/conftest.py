"""One live server per backend for this directory's tests (a server takes seconds to start);
each test gets its own kb."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from service_support import LiveServer, fresh_postgres_database, run_live_server

from client import CpkbClient


@pytest.fixture(
    scope="session", params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)]
)
def shared_server(
    request: pytest.FixtureRequest,
    tmp_path_factory: pytest.TempPathFactory,
    postgres_unreachable_reason: str | None,
) -> Iterator[LiveServer]:
    tmp: Path = tmp_path_factory.mktemp("server")
    if request.param == "sqlite":
        with run_live_server(f"sqlite:///{tmp / 'kb.sqlite'}", tmp / "server.log") as server:
            yield server
        return
    with (
        fresh_postgres_database(postgres_unreachable_reason) as url,
        run_live_server(url, tmp / "server.log") as server,
    ):
        yield server


@pytest.fixture
def kb_client(shared_server: LiveServer) -> Iterator[tuple[CpkbClient, str]]:
    """A client of the shared server and the name of a knowledge base of its own."""
    name = f"t-{uuid.uuid4().hex[:10]}"
    with CpkbClient(shared_server.url, retries=2, backoff=0.05) as client:
        client.create_kb(name)
        yield client, name

"""A real knowledge-base service for planner tests: `cpkb serve` on a fresh SQLite file, started
once per session (it takes seconds to start); every test gets its own fresh knowledge base."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest


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

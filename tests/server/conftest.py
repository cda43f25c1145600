"""Fixtures of the surrogate endpoint tests (suggest, predict, models)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from service_support import at_head
from suggest_support import make_client


@pytest.fixture
def client(sqlite_url: str, migrated_sqlite: Path) -> Iterator[Any]:
    """An in-process service on a fresh SQLite file (at head), fitting in a thread."""
    with make_client(at_head(sqlite_url, migrated_sqlite)) as c:
        yield c

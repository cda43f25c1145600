"""Fixtures of the surrogate endpoint tests (suggest, predict, models)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from suggest_support import make_client


@pytest.fixture
def client(sqlite_url: str) -> Iterator[Any]:
    """An in-process service on a fresh SQLite file, fitting in a thread."""
    with make_client(sqlite_url) as c:
        yield c

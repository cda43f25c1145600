"""Bringing a database up to date: migrations to head, then the `default` knowledge base.

Kept apart from `server.app` so that `cpkb db upgrade` does not import the web stack.
"""

from __future__ import annotations

from migrations import upgrade
from server.db import Store
from server.services.kbs import DEFAULT_KB, ensure_kb


def prepare_database(store: Store) -> None:
    """Migrate to head and create the `default` knowledge base (idempotent, race-safe)."""
    upgrade(store.write_engine)
    with store.transaction(write=True) as session:
        ensure_kb(session, DEFAULT_KB)

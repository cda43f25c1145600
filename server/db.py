"""Engines and the one transaction boundary of the service.

SQLite: WAL journal, a busy timeout, foreign keys on, and every write transaction opened with
`BEGIN IMMEDIATE`, so that writers queue on the busy timeout instead of failing with
"database is locked" when a read snapshot would have to be upgraded. PostgreSQL (through
`postgresql+psycopg://`) needs none of that: unique constraints and `ON CONFLICT` settle races.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import Connection, make_url
from sqlalchemy.exc import ArgumentError, SQLAlchemyError
from sqlalchemy.orm import Session

from server.errors import map_db_error

WRITE_OPTION = "cpkb_write"


class DatabaseUrlError(ValueError):
    """The database URL cannot be used (malformed, or a driver that is not installed)."""


def _configure_sqlite(engine: Engine, busy_timeout_ms: int) -> None:
    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, _record: Any) -> None:
        # Hand transaction control to the `begin` hook below (pysqlite's own is off).
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {int(busy_timeout_ms)}")
        cursor.execute("PRAGMA journal_mode = WAL")
        cursor.execute("PRAGMA synchronous = NORMAL")
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        write = conn.get_execution_options().get(WRITE_OPTION, False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


def make_engine(url: str, *, busy_timeout_ms: int = 30_000, pool_size: int = 10) -> Engine:
    """An engine for `url` (sqlite:///FILE or postgresql+psycopg://...), configured as above."""
    try:
        parsed = make_url(url)
    except ArgumentError as exc:
        raise DatabaseUrlError(f"not a database URL: {url!r}") from exc
    backend = parsed.get_backend_name()
    try:
        if backend == "sqlite":
            engine = create_engine(
                parsed,
                connect_args={"timeout": busy_timeout_ms / 1000, "check_same_thread": False},
                pool_size=pool_size,
                max_overflow=2 * pool_size,
            )
            _configure_sqlite(engine, busy_timeout_ms)
            return engine
        if backend == "postgresql":
            return create_engine(
                parsed, pool_size=pool_size, max_overflow=2 * pool_size, pool_pre_ping=True
            )
    except (ArgumentError, ImportError) as exc:
        raise DatabaseUrlError(f"cannot use database URL {parsed!r}: {exc}") from exc
    raise DatabaseUrlError(
        f"unsupported database {backend!r}: use sqlite:///FILE or postgresql+psycopg://..."
    )


class Store:
    """The database of one service: an engine plus read and write transactions."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._write_engine = engine.execution_options(**{WRITE_OPTION: True})

    @classmethod
    def from_url(cls, url: str, *, busy_timeout_ms: int = 30_000, pool_size: int = 10) -> Store:
        return cls(make_engine(url, busy_timeout_ms=busy_timeout_ms, pool_size=pool_size))

    @property
    def write_engine(self) -> Engine:
        """The engine whose transactions write (on SQLite: `BEGIN IMMEDIATE`)."""
        return self._write_engine

    @property
    def dialect(self) -> str:
        return self.engine.dialect.name

    @contextmanager
    def transaction(self, *, write: bool = False) -> Iterator[Session]:
        """The transaction boundary: commit on success, roll back on any error, and raise
        database errors as `ServiceError`s (409 / 422 / 503), never as a bare exception."""
        session = Session(self._write_engine if write else self.engine, expire_on_commit=False)
        try:
            yield session
            session.commit()
        except SQLAlchemyError as exc:
            session.rollback()
            raise map_db_error(exc) from exc
        except BaseException:
            session.rollback()
            raise
        finally:
            session.close()

    def dispose(self) -> None:
        self.engine.dispose()

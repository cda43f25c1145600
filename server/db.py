"""Engines and the one transaction boundary of the service.

SQLite: WAL journal, a busy timeout, foreign keys on, `synchronous` as configured, and every
write transaction opened with `BEGIN IMMEDIATE`, so that writers queue on the busy timeout
instead of failing with "database is locked" when a read snapshot would have to be upgraded.
PostgreSQL (through `postgresql+psycopg://`): unique constraints and `ON CONFLICT` settle races,
and every connection bounds its lock waits and its idle transactions, so that a replica frozen
mid-transaction (a paused VM) holds the others up for seconds, not until it wakes.

The health probe has an engine of its own (one connection, short timeouts): it never waits for
a connection that writers hold.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

from sqlalchemy import Engine, create_engine, event, text
from sqlalchemy.engine import URL, Connection, make_url
from sqlalchemy.exc import ArgumentError, SQLAlchemyError
from sqlalchemy.orm import Session

from server.errors import map_db_error

WRITE_OPTION = "cpkb_write"
SqliteSynchronous = Literal["NORMAL", "FULL"]
PROBE_TIMEOUT_S = 5


class DatabaseUrlError(ValueError):
    """The database URL cannot be used (malformed, or a driver that is not installed)."""


@dataclass(frozen=True)
class EngineOptions:
    """How the service's connections behave; `server.settings.Settings` sets each from the
    environment (`CPKB_SQLITE_SYNCHRONOUS`, `CPKB_PG_LOCK_TIMEOUT_MS`, ...)."""

    busy_timeout_ms: int = 30_000
    pool_size: int = 10
    # NORMAL (WAL): a commit survives a crash of the process, the last commits before a power
    # cut may not; FULL syncs the WAL at every commit, so they do, at a cost per commit.
    sqlite_synchronous: SqliteSynchronous = "NORMAL"
    # PostgreSQL: a statement waiting longer for a lock fails (the request answers 503 with
    # Retry-After, and the client retries); 0 waits for ever.
    pg_lock_timeout_ms: int = 3_000
    # PostgreSQL ends a session idle inside a transaction this long, releasing its locks (a
    # frozen replica's); 0: never.
    pg_idle_in_transaction_timeout_ms: int = 5_000
    # Names this service's sessions in pg_stat_activity.
    application_name: str = "cpkb"


def _configure_sqlite(engine: Engine, busy_timeout_ms: int, synchronous: str) -> None:
    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, _record: Any) -> None:
        # Hand transaction control to the `begin` hook below (pysqlite's own is off).
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute(f"PRAGMA busy_timeout = {int(busy_timeout_ms)}")
        cursor.execute("PRAGMA journal_mode = WAL")
        cursor.execute(f"PRAGMA synchronous = {synchronous}")
        cursor.execute("PRAGMA foreign_keys = ON")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        write = conn.get_execution_options().get(WRITE_OPTION, False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


def make_engine(url: str, options: EngineOptions | None = None) -> Engine:
    """An engine for `url` (sqlite:///FILE or postgresql+psycopg://...), configured as above."""
    options = options or EngineOptions()
    parsed = _parse(url)
    backend = parsed.get_backend_name()
    pool = {"pool_size": options.pool_size, "max_overflow": 2 * options.pool_size}
    try:
        if backend == "sqlite":
            engine = create_engine(parsed, connect_args=_sqlite_args(options), **pool)
            _configure_sqlite(engine, options.busy_timeout_ms, options.sqlite_synchronous)
            return engine
        if backend == "postgresql":
            args = _postgres_args(options)
            return create_engine(parsed, connect_args=args, pool_pre_ping=True, **pool)
    except (ArgumentError, ImportError) as exc:
        raise DatabaseUrlError(f"cannot use database URL {parsed!r}: {exc}") from exc
    raise DatabaseUrlError(
        f"unsupported database {backend!r}: use sqlite:///FILE or postgresql+psycopg://..."
    )


def make_probe_engine(url: str, options: EngineOptions | None = None) -> Engine:
    """One connection for the health probe, apart from the pool that requests share, with
    timeouts short enough that a probe of a stuck database answers (503) rather than hangs."""
    options = options or EngineOptions()
    parsed = _parse(url)
    pool = {"pool_size": 1, "max_overflow": 0, "pool_timeout": PROBE_TIMEOUT_S}
    if parsed.get_backend_name() == "sqlite":
        quick = EngineOptions(busy_timeout_ms=PROBE_TIMEOUT_S * 1000)
        return create_engine(parsed, connect_args=_sqlite_args(quick), **pool)
    args = _postgres_args(options) | {"connect_timeout": PROBE_TIMEOUT_S}
    args["options"] += f" -c statement_timeout={PROBE_TIMEOUT_S * 1000}"
    return create_engine(parsed, connect_args=args, pool_pre_ping=True, **pool)


def _parse(url: str) -> URL:
    try:
        return make_url(url)
    except ArgumentError as exc:
        raise DatabaseUrlError(f"not a database URL: {url!r}") from exc


def _sqlite_args(options: EngineOptions) -> dict[str, Any]:
    return {"timeout": options.busy_timeout_ms / 1000, "check_same_thread": False}


def _postgres_args(options: EngineOptions) -> dict[str, Any]:
    settings = (
        f"-c lock_timeout={options.pg_lock_timeout_ms} "
        f"-c idle_in_transaction_session_timeout={options.pg_idle_in_transaction_timeout_ms}"
    )
    return {"options": settings, "application_name": options.application_name[:63]}


class Store:
    """The database of one service: an engine plus read and write transactions, and a
    probe of its own for health checks."""

    def __init__(self, engine: Engine, probe: Engine | None = None) -> None:
        self.engine = engine
        self._write_engine = engine.execution_options(**{WRITE_OPTION: True})
        self._probe = probe

    @classmethod
    def from_url(cls, url: str, options: EngineOptions | None = None) -> Store:
        return cls(make_engine(url, options), make_probe_engine(url, options))

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

    def ping(self) -> None:
        """`SELECT 1` on the probe's own connection (the shared pool's when it has none);
        raises `Unavailable` when the database does not answer."""
        try:
            with (self._probe or self.engine).connect() as conn:
                conn.execute(text("SELECT 1"))
        except SQLAlchemyError as exc:
            raise map_db_error(exc) from exc

    def dispose(self) -> None:
        self.engine.dispose()
        if self._probe is not None:
            self._probe.dispose()

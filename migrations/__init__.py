"""Alembic migrations, configured in code so that they run from an installed package.

The version table is `cpkb_alembic_version`, so a database shared with another alembic user
does not clash. `upgrade(engine)` brings a database to head in one transaction under a lock
(PostgreSQL: an advisory lock; SQLite: the write lock of the `BEGIN IMMEDIATE` that the
service's write engine, `server.db.Store.write_engine`, begins with), so that services
starting at once on one database migrate it once.

Imports nothing of the service: the service runs its migrations (`server.schema`), not the
other way round. A new revision is written against the service's tables by handing them in,
on a connection to a database at head: `config = alembic_config(connection)`,
`config.attributes["target_metadata"] = server.orm.Base.metadata`, then
`alembic.command.revision(config, "message", autogenerate=True, rev_id="0005")`.
`tests/migrations/test_schema_migrations.py` checks that the tables and the revisions agree.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Connection, Engine, text

MIGRATIONS_DIR = Path(__file__).resolve().parent
VERSION_TABLE = "cpkb_alembic_version"
_PG_LOCK_KEY = 0x63706B62  # "cpkb"


def alembic_config(connection: Connection | None = None) -> Config:
    """An alembic Config without an ini file; `connection` is handed to env.py."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    config.set_main_option("version_table", VERSION_TABLE)
    if connection is not None:
        config.attributes["connection"] = connection
    return config


def upgrade(engine: Engine, revision: str = "head") -> None:
    """Migrate the database behind `engine` to `revision`, in one locked transaction."""
    with engine.begin() as conn:
        if engine.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _PG_LOCK_KEY})
        command.upgrade(alembic_config(conn), revision)


def downgrade(engine: Engine, revision: str) -> None:
    with engine.begin() as conn:
        command.downgrade(alembic_config(conn), revision)


def current_revision(engine: Engine) -> str | None:
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"version_table": VERSION_TABLE})
        return context.get_current_revision()

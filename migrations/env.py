"""Alembic environment: online only, on the connection handed in by `migrations.upgrade`."""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection, create_engine

config = context.config
# Only writing a revision compares tables (see `migrations`); upgrades run the revisions as such.
target_metadata = config.attributes.get("target_metadata")


def _configure_and_run(connection: Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        version_table=config.get_main_option("version_table") or "cpkb_alembic_version",
        render_as_batch=connection.dialect.name == "sqlite",
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


connection = config.attributes.get("connection")
if connection is not None:
    _configure_and_run(connection)
else:
    url = config.get_main_option("sqlalchemy.url")
    if not url:
        raise RuntimeError("run migrations through migrations.upgrade() or `cpkb db upgrade`")
    engine = create_engine(url)
    with engine.begin() as conn:
        _configure_and_run(conn)
    engine.dispose()

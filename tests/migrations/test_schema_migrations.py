"""Migrations: an empty database goes to head, and the models agree with the migrations."""

from __future__ import annotations

import subprocess
import sys

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect, text

from migrations import VERSION_TABLE, current_revision, downgrade, upgrade
from server.db import make_engine
from server.orm import Base

HEAD = "0006"


def test_empty_database_to_head_and_no_autogenerate_diff(db_url: str) -> None:
    engine = make_engine(db_url)
    try:
        assert current_revision(engine) is None
        upgrade(engine)
        upgrade(engine)  # idempotent
        assert current_revision(engine) == HEAD
        tables = set(inspect(engine).get_table_names())
        assert {"knowledge_bases", "cp_types", "cp_points", VERSION_TABLE} <= tables
        assert "alembic_version" not in tables
        with engine.connect() as conn:
            context = MigrationContext.configure(
                conn, opts={"compare_type": True, "version_table": VERSION_TABLE}
            )
            assert compare_metadata(context, Base.metadata) == []
    finally:
        engine.dispose()


def test_downgrade_to_base_and_back(db_url: str) -> None:
    engine = make_engine(db_url)
    try:
        upgrade(engine)
        downgrade(engine, "base")
        assert set(inspect(engine).get_table_names()) <= {VERSION_TABLE}
        upgrade(engine)
        assert current_revision(engine) == HEAD
    finally:
        engine.dispose()


def test_0006_drops_the_entries_planners_reported_and_keeps_those_served(db_url: str) -> None:
    """The pending exchange is retired: its rows (an owner's) go with the column, the
    suggestions the service served stay; downgrading brings the column back, empty."""
    engine = make_engine(db_url)
    try:
        upgrade(engine, "0005")
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO knowledge_bases (name, created_at) "
                    "VALUES ('lab', CURRENT_TIMESTAMP)"
                )
            )
            kb = conn.execute(text("SELECT id FROM knowledge_bases WHERE name = 'lab'")).scalar()
            for owner in (None, "run-a"):
                conn.execute(
                    text(
                        "INSERT INTO cp_pending (kb_id, x, binds, owner, expires_at) "
                        "VALUES (:kb, '{}', '[]', :owner, CURRENT_TIMESTAMP)"
                    ),
                    {"kb": kb, "owner": owner},
                )
        upgrade(engine)
        assert "owner" not in {c["name"] for c in inspect(engine).get_columns("cp_pending")}
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM cp_pending")).scalar() == 1
        downgrade(engine, "0005")
        assert "owner" in {c["name"] for c in inspect(engine).get_columns("cp_pending")}
    finally:
        engine.dispose()


def test_cpkb_db_upgrade_from_an_installed_package(sqlite_url: str, tmp_path: object) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "cpkb", "db", "upgrade", "--db", sqlite_url],
        capture_output=True,
        text=True,
        cwd=str(tmp_path),
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert f"schema at revision {HEAD}" in out.stdout

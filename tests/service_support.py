"""Helpers for tests of the knowledge-base service: graphs and points to post, fresh
PostgreSQL databases, live servers (the fixtures in tests/conftest.py wrap these)."""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

POSE_DOMAIN = {"kind": "continuous", "low": [0.0, 0.0, -3.0], "high": [1.0, 1.0, 3.0]}
DIR_DOMAIN = {"kind": "categorical", "choices": ["front", "right", "top", "back", "left"]}


def make_graph(
    failure: str = "Inv-kin",
    context: tuple[str, ...] = ("box1",),
    *,
    pose_domain: dict[str, Any] | None = None,
    prefix: str = "",
) -> dict[str, Any]:
    """A small causal graph: #dir and #pose feed the failure, context bodies collide with it.

    `prefix` renames the node ids (the type must not change); `pose_domain` overrides #pose's.
    """
    nodes = [
        {"id": f"{prefix}f", "role": "failure", "label": failure},
        {"id": f"{prefix}d", "role": "decision", "label": "#dir", "domain": DIR_DOMAIN},
        {
            "id": f"{prefix}p",
            "role": "decision",
            "label": "#pose",
            "domain": pose_domain or POSE_DOMAIN,
        },
    ]
    edges = [
        {"source": f"{prefix}d", "target": f"{prefix}f", "label": "grasp"},
        {"source": f"{prefix}p", "target": f"{prefix}f", "label": "pose"},
    ]
    for i, body in enumerate(context):
        nodes.append({"id": f"{prefix}c{i}", "role": "context", "label": body})
        edges.append({"source": f"{prefix}c{i}", "target": f"{prefix}f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


def make_point(
    i: int = 0,
    *,
    graph: dict[str, Any] | None = None,
    key: str | None = "auto",
    feasible: bool | None = None,
    **source: Any,
) -> dict[str, Any]:
    """Point number `i` of `graph` (deterministic x); `key="auto"` gives a fresh unique key."""
    point: dict[str, Any] = {
        "graph": graph or make_graph(),
        "x": {
            "#dir": DIR_DOMAIN["choices"][i % 5],
            "#pose": [(i % 10) / 10, (i % 7) / 7, -3.0 + (i % 13) * 0.5],
        },
        "feasible": (i % 3 == 0) if feasible is None else feasible,
    }
    if key == "auto":
        point["key"] = uuid.uuid4().hex
    elif key is not None:
        point["key"] = key
    if source:
        point["source"] = source
    return point


def collision_pair() -> tuple[dict[str, Any], dict[str, Any]]:
    """A directed 6-cycle and two directed 3-cycles, every cycle node fed by the failure:
    not isomorphic, yet Weisfeiler-Lehman gives every cycle node the same colour in both."""
    domain = {"kind": "categorical", "choices": ["a", "b"]}

    def graph(cycles: list[list[int]]) -> dict[str, Any]:
        nodes = [
            {"id": "f", "role": "failure", "label": "Plan-motion"},
            {"id": "k", "role": "decision", "label": "#k", "domain": domain},
        ]
        edges = [{"source": "k", "target": "f", "label": "feeds"}]
        for cycle in cycles:
            for i, n in enumerate(cycle):
                nodes.append({"id": f"c{n}", "role": "connection", "label": "link"})
                nxt = cycle[(i + 1) % len(cycle)]
                edges.append({"source": f"c{n}", "target": f"c{nxt}", "label": "next"})
                edges.append({"source": "f", "target": f"c{n}", "label": "via"})
        return {"nodes": nodes, "edges": edges}

    return graph([[0, 1, 2, 3, 4, 5]]), graph([[0, 1, 2], [3, 4, 5]])


DEFAULT_TEST_POSTGRES_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


def postgres_admin_url() -> str:
    return os.environ.get("CPKB_TEST_POSTGRES_URL", DEFAULT_TEST_POSTGRES_URL)


@contextmanager
def fresh_postgres_database(reason_unreachable: str | None) -> Iterator[str]:
    """A new, empty database on the test server (its URL), dropped on exit."""
    if reason_unreachable is not None:
        pytest.skip(reason_unreachable)
    import psycopg
    from sqlalchemy.engine import make_url

    admin = make_url(postgres_admin_url())
    admin_dsn = admin.set(drivername="postgresql").render_as_string(hide_password=False)
    name = f"cpkb_t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(admin_dsn, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        yield admin.set(database=name).render_as_string(hide_password=False)
    finally:
        with psycopg.connect(admin_dsn, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


@dataclass(frozen=True)
class LiveServer:
    url: str
    db_url: str
    log: Path


@contextmanager
def run_live_server(
    db_url: str, log: Path, env: dict[str, str] | None = None
) -> Iterator[LiveServer]:
    """`cpkb serve` on `db_url` in a subprocess (extra `env`), its output appended to `log`."""
    from cpkb.embedded import embedded_service

    with embedded_service(db_url, log_file=log, env=env) as url:
        yield LiveServer(url=url, db_url=db_url, log=log)


def at_head(url: str, migrated: Path) -> str:
    """`url`, its SQLite file (not there yet) made a copy of `migrated`, a database brought to
    head (the `migrated_sqlite` fixture); any other URL as it is."""
    if url.startswith("sqlite:///"):
        shutil.copyfile(migrated, url.removeprefix("sqlite:///"))
    return url

"""Shared by the fuzz tests: the hypothesis profile, settings for a fresh SQLite app, and a
snapshot of everything the server stores, so that a test can say "this request changed nothing"."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings

from server.settings import Settings

settings.register_profile(
    "fuzz",
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    derandomize=True,
)
FUZZ = settings.get_profile("fuzz")
# A small limit so that an oversized body is cheap to send.
MAX_BODY_BYTES = 256 * 1024


def make_settings(db_path: Path, **overrides: Any) -> Settings:
    values: dict[str, Any] = {
        "database_url": f"sqlite:///{db_path}",
        "max_body_bytes": MAX_BODY_BYTES,
        "token": None,
        "tokens_file": None,
        "auth_reads": False,
        "cors_origins": [],
    }
    return Settings(**(values | overrides))


def snapshot(client: TestClient) -> dict[str, Any]:
    """Every knowledge base, type and point the server holds (small test databases only)."""
    state: dict[str, Any] = {}
    kbs = client.get("/v1/kbs").raise_for_status().json()
    for kb in kbs:
        name = kb["name"]
        types = client.get(f"/v1/kbs/{name}/types").raise_for_status().json()
        points = {}
        for t in types:
            page = client.get(f"/v1/kbs/{name}/types/{t['type_id']}/points", params={"limit": 1000})
            points[t["type_id"]] = page.raise_for_status().json()["points"]
        state[name] = {"kb": kb, "types": types, "points": points}
    return state

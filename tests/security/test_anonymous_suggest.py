"""A `/suggest` from a caller without write access is answered, but recorded nowhere: it does
not move what the planners with the token are told (on both backends: SQLite keeps pending
suggestions in the service's memory, PostgreSQL in its database)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from service_support import DIR_DOMAIN, POSE_DOMAIN, make_point
from sqlalchemy import func, select

from server.app import create_app
from server.orm import PendingRow
from server.settings import Settings

TOKEN = "correct-horse-battery-staple"
SUGGEST = "/v1/kbs/default/suggest"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture
def guarded(db_url: str) -> Iterator[TestClient]:
    settings = Settings(database_url=db_url, token=TOKEN, surrogate_fit_process=False)
    with TestClient(create_app(settings)) as client:
        yield client


def a_type(client: TestClient) -> str:
    points = [make_point(i) for i in range(12)]
    response = client.post("/v1/kbs/default/points", json={"points": points}, headers=AUTH)
    assert response.status_code == 201, response.text
    return response.json()["results"][0]["type_id"]


def suggest(
    client: TestClient, type_id: str, headers: dict[str, str], n: int = 1
) -> dict[str, Any]:
    request = {
        "space": {"d": DIR_DOMAIN, "p": POSE_DOMAIN},
        "constraints": [{"type_id": type_id, "bind": {"#dir": "d", "#pose": "p"}}],
        "seed": 3,
        "n": n,
    }
    response = client.post(SUGGEST, json=request, headers=headers)
    assert response.status_code == 200, response.text
    return response.json()


def stored_pending(client: TestClient) -> int:
    with client.app.state.store.transaction() as session:
        return session.scalar(select(func.count()).select_from(PendingRow)) or 0


@pytest.mark.parametrize(
    "headers", [{}, {"Authorization": "Bearer wrong"}], ids=["anonymous", "bad-token"]
)
def test_suggestions_without_write_access_change_nothing_others_are_told(
    guarded: TestClient, headers: dict[str, str]
) -> None:
    type_id = a_type(guarded)
    for _ in range(10):
        answer = suggest(guarded, type_id, headers, n=32)
        assert len(answer["batch"]) > 1
    assert stored_pending(guarded) == 0
    planner = suggest(guarded, type_id, AUTH)
    assert planner["n_pending"] == 0
    # The planner's own suggestion is recorded: the next one is kept away from it.
    assert suggest(guarded, type_id, AUTH)["n_pending"] == 1

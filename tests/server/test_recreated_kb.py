"""A knowledge base deleted and created again under its name learns from its own points only:
no model of the deleted one is served, whether this service or another one deleted it
(SQLite reuses the row and point ids, so ids alone cannot tell the two apart)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from service_support import make_point

from server.app import create_app
from server.settings import Settings

KB = "/v1/kbs/lab"
PROBE = {"#dir": "top", "#pose": [0.5, 0.5, 0.0]}


@pytest.fixture
def fitting(db_url: str) -> Iterator[TestClient]:
    """A service that fits (in a thread) and checks a type's points on every request."""
    settings = Settings(database_url=db_url, surrogate={"fit_process": False, "refresh_s": 0})
    with TestClient(create_app(settings)) as client:
        yield client


def post(client: TestClient, n: int, *, feasible: bool) -> str:
    points = [make_point(i, feasible=feasible) for i in range(n)]
    answer = client.post(f"{KB}/points", json={"points": points})
    assert answer.status_code == 201, answer.text
    return answer.json()["results"][0]["type_id"]


def model_of(client: TestClient, type_id: str) -> tuple[dict[str, Any], float]:
    """(surrogate state, P(feasible) of the probe) once the engine is idle."""
    assert client.app.state.surrogates.wait_idle(timeout=300)
    answer = client.post(f"{KB}/types/{type_id}/predict", json={"x": [PROBE]})
    assert answer.status_code == 200, answer.text
    state = client.get(f"{KB}/types/{type_id}").json()["surrogate"]
    return state, answer.json()["p_feasible"][0]


def learn_infeasible(client: TestClient) -> str:
    assert client.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    type_id = post(client, 100, feasible=False)
    state, p = model_of(client, type_id)
    assert state["n_points"] == 100 and p < 0.5
    return type_id


def test_a_kb_deleted_here_and_created_again_starts_afresh(fitting: TestClient) -> None:
    type_id = learn_infeasible(fitting)
    assert fitting.delete(KB).status_code == 204
    assert fitting.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    assert post(fitting, 30, feasible=True) == type_id
    state, p = model_of(fitting, type_id)
    assert state["n_points"] == 30 and state["n_fitted"] == 30, state
    assert p > 0.5


def test_a_kb_deleted_elsewhere_and_created_again_starts_afresh(
    fitting: TestClient, core_client: TestClient
) -> None:
    other = core_client  # a second service on the same database, without a surrogate engine
    type_id = learn_infeasible(fitting)
    assert other.delete(KB).status_code == 204
    assert other.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    assert post(other, 30, feasible=True) == type_id
    state, p = model_of(fitting, type_id)
    assert state["n_points"] == 30, state
    assert p > 0.5

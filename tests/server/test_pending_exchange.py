"""POST /v1/kbs/{kb}/pending: planners that suggest in their own processes share what is
pending, with each other and with the service's own suggest."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from suggest_support import BIND, make_client, post_points, suggest_body

PENDING = "/v1/kbs/default/pending"


def served(x: dict[str, Any], type_ids: list[str], bind: dict[str, str] = BIND) -> dict[str, Any]:
    return {"x": x, "binds": [{"type_id": t, "bind": dict(bind)} for t in type_ids]}


def exchange(client: Any, run: str, points: list[dict[str, Any]], type_ids: list[str]) -> list:
    response = client.post(PENDING, json={"run": run, "served": points, "type_ids": type_ids})
    assert response.status_code == 200, response.text
    return response.json()["pending"]


@pytest.fixture(params=["memory", "database"])
def books(request: pytest.FixtureRequest, sqlite_url: str) -> Iterator[Any]:
    """A service whose pending book is in its process, or in its database (replicas)."""
    with make_client(sqlite_url, pending_store=request.param) as c:
        yield c


def test_each_run_gets_the_others_pending_points_and_its_report_replaces_the_last(books):
    client = books
    with client:
        reach, clear = post_points(client, 4)
        a1 = served({"d": "top", "p": [0.9, 0.1, 0.0]}, [reach])
        a2 = served({"d": "left", "p": [0.2, 0.3, 1.0]}, [reach, clear])
        assert exchange(client, "a", [a1, a2], [reach]) == []
        assert exchange(client, "b", [], [reach]) == [a1, a2]
        assert exchange(client, "b", [], [clear]) == [a2]
        assert exchange(client, "a", [a2], [reach]) == []  # a1 was answered meanwhile
        assert exchange(client, "b", [], [reach, clear]) == [a2]
        assert exchange(client, "a", [], []) == []  # a run withdraws what is left when done
        assert exchange(client, "b", [], [reach, clear]) == []


def test_the_services_suggest_keeps_away_from_a_reported_point_and_it_comes_back(client):
    with client:
        type_ids = post_points(client, 4)
        reported = served({"d": "top", "p": [0.9, 0.1, 0.0]}, type_ids)
        exchange(client, "a", [reported], type_ids)
        answer = client.post("/v1/kbs/default/suggest", json=suggest_body(type_ids, seed=0))
        assert answer.status_code == 200 and answer.json()["n_pending"] == 1
        back = exchange(client, "a", [reported], type_ids)
        assert [p["x"] for p in back] == [answer.json()["x"]]  # the service's own, for "a"


def test_bad_pending_reports_are_clear_4xx(client):
    with client:
        (type_id, _) = post_points(client, 2)
        good = served({"d": "top", "p": [0.9, 0.1, 0.0]}, [type_id])
        missing = client.post("/v1/kbs/nope/pending", json={"run": "a", "type_ids": [type_id]})
        assert missing.status_code == 404
        for body in (
            {"served": [good], "type_ids": [type_id]},  # no run
            {"run": "a", "served": [{**good, "binds": []}]},  # a point for no type
            {"run": "a", "served": [good] * 257},  # more than a report holds
            {"run": "", "served": [good]},
            {"run": "a", "served": [good], "extra": 1},
        ):
            answer = client.post(PENDING, json=body)
            assert answer.status_code == 422, (body, answer.text)

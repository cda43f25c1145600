"""POST /v1/kbs/{kb}/points/since: other writers' new points of watched types, on both backends."""

from __future__ import annotations

from typing import Any

import pytest
from service_support import make_graph, make_point

POINTS = "/v1/kbs/default/points"
SINCE = "/v1/kbs/default/points/since"


def post(client: Any, points: list[dict[str, Any]]) -> list[dict[str, Any]]:
    response = client.post(POINTS, json={"points": points})
    assert response.status_code == 201, response.text
    return response.json()["results"]


def since(client: Any, **body: Any) -> dict[str, Any]:
    response = client.post(SINCE, json=body)
    assert response.status_code == 200, response.text
    return response.json()


def test_points_after_the_cursor_of_watched_types_without_the_callers_own(
    core_client: Any,
) -> None:
    ours, theirs, unwatched = make_graph(), make_graph(context=("box2",)), make_graph("Collide")
    first = post(core_client, [make_point(0, graph=ours, run="a")])
    type_id = first[0]["type_id"]
    start = since(core_client, type_ids=[type_id])
    assert start["points"] == [] and start["cursor"] >= first[0]["point_id"]

    watched_later = post(core_client, [make_point(1, graph=theirs, run="b")])[0]["type_id"]
    post(core_client, [make_point(2, graph=unwatched, run="b")])
    mine = post(core_client, [make_point(3, graph=ours, run="a")])
    new = post(core_client, [make_point(4, graph=ours, run="b"), make_point(5, graph=theirs)])
    answer = since(
        core_client,
        type_ids=[type_id, watched_later],
        after_point_id=start["cursor"],
        exclude_run="a",
    )
    ids = [p["point_id"] for p in answer["points"]]
    assert ids == sorted(ids) and min(ids) > start["cursor"]
    got = {(p["type_id"], p["run"]) for p in answer["points"]}
    assert got == {(type_id, "b"), (watched_later, "b"), (watched_later, None)}
    assert mine[0]["point_id"] not in {p["point_id"] for p in answer["points"]}
    assert answer["cursor"] == max(r["point_id"] for r in new) and not answer["more"]
    x = make_point(4, graph=ours)["x"]
    assert next(p for p in answer["points"] if p["type_id"] == type_id)["x"] == x

    again = since(core_client, type_ids=[type_id, watched_later], after_point_id=answer["cursor"])
    assert again["points"] == [] and again["cursor"] == answer["cursor"]


def test_a_type_watched_before_it_exists_comes_with_its_first_points(core_client: Any) -> None:
    post(core_client, [make_point(0, run="a")])
    cursor = since(core_client, type_ids=[])["cursor"]
    absent = "0" * 64
    assert since(core_client, type_ids=[absent], after_point_id=cursor)["points"] == []
    born = post(core_client, [make_point(1, graph=make_graph("Collide"), run="b")])[0]
    answer = since(core_client, type_ids=[absent, born["type_id"]], after_point_id=cursor)
    assert [p["point_id"] for p in answer["points"]] == [born["point_id"]]


def test_a_limit_cuts_the_answer_at_a_cursor_that_resumes_it(core_client: Any) -> None:
    results = post(core_client, [make_point(i, run="b") for i in range(7)])
    type_ids = [results[0]["type_id"]]
    cursor, seen, pages = 0, [], 0
    while True:
        answer = since(core_client, type_ids=type_ids, after_point_id=cursor, limit=3)
        seen += [p["point_id"] for p in answer["points"]]
        cursor, pages = answer["cursor"], pages + 1
        if not answer["more"]:
            break
    assert seen == [r["point_id"] for r in results] and pages == 3


@pytest.mark.parametrize(
    "body",
    [
        {"type_ids": ["t"], "after_point_id": -1},
        {"type_ids": ["t"], "after_point_id": 2**63},
        {"type_ids": ["t"], "after_point_id": "ten"},
        {"type_ids": "t"},
        {"type_ids": [""]},
        {"type_ids": ["t"] * 513},
        {"type_ids": ["t"], "limit": 0},
        {"type_ids": ["t"], "limit": 1001},
        {"type_ids": ["t"], "exclude_run": "a\u0000b"},
        {"type_ids": ["t"], "since": 3},
        {},
    ],
)
def test_bad_input_is_a_clear_422(core_client: Any, body: dict[str, Any]) -> None:
    response = core_client.post(SINCE, json=body)
    assert response.status_code == 422, response.text
    assert response.json()["detail"]


def test_an_unknown_knowledge_base_is_a_404(core_client: Any) -> None:
    response = core_client.post("/v1/kbs/nowhere/points/since", json={"type_ids": []})
    assert response.status_code == 404, response.text

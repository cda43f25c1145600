"""Bad input that once broke the service (a 500, or data no reader could serialise back) gets a
clear 4xx on both backends, and what a type already holds stays readable."""

from __future__ import annotations

import json
from typing import Any

from service_support import make_graph, make_point
from sqlalchemy import update

from contract.models import MAX_SOURCE_DEPTH
from server.db import Store
from server.orm import PointRow

POINTS = "/v1/kbs/default/points"


def nested(depth: int) -> Any:
    """A list `depth` levels deep around one number."""
    value: Any = 1
    for _ in range(depth):
        value = [value]
    return value


def depth(value: Any) -> int:
    levels = 0
    while isinstance(value, list):
        value, levels = value[0], levels + 1
    return levels


def post_json_text(client: Any, path: str, text: str) -> Any:
    return client.post(path, content=text, headers={"content-type": "application/json"})


def assert_clear_refusal(response: Any, status: int = 422) -> str:
    """The status, and a detail that is JSON text (answer bodies must be encodable)."""
    assert response.status_code == status, (response.status_code, response.text[:500])
    detail = response.json()["detail"]
    assert detail
    return json.dumps(detail)


def stored_point_count(client: Any) -> int:
    return client.get("/v1/kbs/default").json()["n_points"]


def type_points(client: Any, type_id: str, **params: Any) -> Any:
    return client.get(f"/v1/kbs/default/types/{type_id}/points", params=params)


def test_a_deeply_nested_source_is_refused_at_ingest(core_client: Any) -> None:
    deep = make_point(1, note=nested(256))
    detail = assert_clear_refusal(core_client.post(POINTS, json={"points": [deep]}))
    assert f"deeper than {MAX_SOURCE_DEPTH}" in detail
    assert stored_point_count(core_client) == 0
    # `source` is the first level: its deepest allowed value is MAX_SOURCE_DEPTH - 1 deep.
    deepest = make_point(2, note=nested(MAX_SOURCE_DEPTH - 1))
    stored = core_client.post(POINTS, json={"points": [deepest]})
    assert stored.status_code == 201, stored.text
    (result,) = stored.json()["results"]
    page = type_points(core_client, result["type_id"])
    assert page.status_code == 200, page.text
    assert page.json()["points"][0]["source"]["note"] == nested(MAX_SOURCE_DEPTH - 1)


def test_a_deep_source_stored_before_the_bound_stays_readable(
    core_client: Any, db_url: str
) -> None:
    posted = core_client.post(POINTS, json={"points": [make_point(1, note="shallow")]})
    (result,) = posted.json()["results"]
    store = Store.from_url(db_url)
    try:
        with store.transaction(write=True) as session:
            session.execute(update(PointRow).values(extra={"note": nested(256)}))
    finally:
        store.dispose()
    page = type_points(core_client, result["type_id"])
    assert page.status_code == 200, page.text[:500]
    note = page.json()["points"][0]["source"]["note"]
    # Answered as deep as ingest allows, the rest as its JSON text: nothing is lost.
    answered = depth(note)
    assert answered == MAX_SOURCE_DEPTH - 1
    leaf = note
    for _ in range(answered):
        leaf = leaf[0]
    assert answered + depth(json.loads(leaf)) == 256
    csv = core_client.get(f"/v1/kbs/default/types/{result['type_id']}/points.csv")
    assert csv.status_code == 200


def test_cursors_that_are_not_ids_this_server_gave_out_are_422(core_client: Any) -> None:
    (result,) = core_client.post(POINTS, json={"points": [make_point(1)]}).json()["results"]
    for cursor in ("\u00b2", "\u0663", "9223372036854775808", "9999999999999999999", "-1", "1e3"):
        response = type_points(core_client, result["type_id"], cursor=cursor)
        assert "cursor" in assert_clear_refusal(response), cursor
    last = type_points(core_client, result["type_id"], cursor=str(2**63 - 1))
    assert last.status_code == 200 and last.json()["points"] == []


def test_a_negative_or_huge_seed_is_422(core_client: Any) -> None:
    space = {"d": {"kind": "categorical", "choices": ["a", "b"]}}
    for seed in (-1, 2**63, 2**70):
        body = {"space": space, "seed": seed}
        response = core_client.post("/v1/kbs/default/suggest", json=body)
        assert "seed" in assert_clear_refusal(response), seed


def test_lone_surrogates_and_nul_are_refused_alike_on_both_backends(core_client: Any) -> None:
    """A lone surrogate is valid JSON ("\\ud800") but not UTF-8; PostgreSQL refuses NUL in
    text where SQLite stores it. Each is a 422, in a label, a key or a source."""
    for bad in ("\ud800", "a\udfffb", "a\x00b"):
        graph = make_graph(context=(f"box{bad}",))
        long_graph = make_graph(context=(f"{bad}" + "x" * 200,))
        cases = [
            make_point(1, graph=graph),
            make_point(1, graph=long_graph),  # refused for its length: echoes the label
            make_point(1, key=f"key-{bad}"),
            make_point(1, task=f"task{bad}"),
            make_point(1, note={"deep": [f"v{bad}"]}),
            make_point(1, **{f"k{bad}": 1}),
        ]
        for point in cases:
            response = post_json_text(core_client, POINTS, json.dumps({"points": [point]}))
            assert_clear_refusal(response)
        kb = post_json_text(core_client, "/v1/kbs", json.dumps({"name": f"kb{bad}"}))
        assert_clear_refusal(kb)
    assert stored_point_count(core_client) == 0


def test_booleans_are_not_numbers(core_client: Any) -> None:
    point = make_point(1)
    point["x"]["#pose"] = [True, 0.5, 0.0]
    assert_clear_refusal(core_client.post(POINTS, json={"points": [point]}))
    graph = make_graph(pose_domain={"kind": "continuous", "low": [False], "high": [True]})
    point = make_point(1, graph=graph)
    point["x"]["#pose"] = [0.5]
    assert_clear_refusal(core_client.post(POINTS, json={"points": [point]}))
    assert stored_point_count(core_client) == 0


def test_dot_names_are_not_knowledge_bases(core_client: Any) -> None:
    for name in (".", ".."):
        assert_clear_refusal(core_client.post("/v1/kbs", json={"name": name}))
    assert core_client.post("/v1/kbs", json={"name": "a.b"}).status_code == 201
    assert core_client.post("/v1/kbs", json={"name": "..."}).status_code == 201


def test_a_422_does_not_echo_a_large_input(core_client: Any) -> None:
    big = "z" * 1_000_000
    point = make_point(1, graph=make_graph(context=(big,)))
    response = core_client.post(POINTS, json={"points": [point]})
    assert_clear_refusal(response)
    assert len(response.content) < 10_000
    short = make_point(1)
    short["x"]["#dir"] = 7
    detail = core_client.post(POINTS, json={"points": [short]}).json()["detail"]
    assert any(error.get("input") == 7 for error in detail), detail

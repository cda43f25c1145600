"""Bad input gets a clear 4xx and changes nothing stored; good input of any shape is stored.

Property-based (hypothesis) over graphs and points, plus the named cases of the issue:
oversized bodies, huge graphs, NaN and infinities, wrong dimensions, unknown labels,
non-isomorphic graphs under one hash, unknown knowledge bases.
"""

from __future__ import annotations

import copy
import json
import math
from typing import Any

import pytest
from fastapi.testclient import TestClient
from fuzz_strategies import bad_x, graphs, points, x_for
from fuzz_support import FUZZ, MAX_BODY_BYTES, snapshot
from hypothesis import given
from hypothesis import strategies as st

from contract.models import MAX_EDGES, MAX_NODES

POINTS = "/v1/kbs/default/points"

DIRECTIONS = {"kind": "categorical", "choices": ["front", "top", "left"]}
BOX = {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]}
BASE_GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Inv-kin"},
        {"id": "d", "role": "decision", "label": "#dir", "domain": DIRECTIONS},
        {"id": "p", "role": "decision", "label": "#pose", "domain": BOX},
        {"id": "c", "role": "context", "label": "shelf"},
    ],
    "edges": [
        {"source": "d", "target": "f", "label": "feeds"},
        {"source": "p", "target": "f", "label": "feeds"},
        {"source": "c", "target": "f", "label": "collides"},
    ],
}
GOOD_X = {"#dir": "top", "#pose": [0.25, 0.75]}


def seed(api: TestClient) -> dict[str, Any]:
    """Store one known point and return the server's whole state."""
    body = {"points": [{"graph": BASE_GRAPH, "x": GOOD_X, "feasible": False, "key": "seed-1"}]}
    assert api.post(POINTS, json=body).status_code == 201
    return snapshot(api)


def assert_refused(api: TestClient, response: Any, before: dict[str, Any]) -> None:
    assert 400 <= response.status_code < 500, (response.status_code, response.text[:500])
    detail = response.json()["detail"]
    assert detail, "a refusal says what was wrong"
    assert snapshot(api) == before, "a refused request changed what is stored"


@pytest.mark.slow
@FUZZ
@given(point=points())
def test_any_valid_point_is_stored_or_a_clear_conflict(api: TestClient, point: dict) -> None:
    before = snapshot(api)
    response = api.post(POINTS, json={"points": [point]})
    if response.status_code == 409:
        assert_refused(api, response, before)
        return
    assert response.status_code == 201, response.text[:500]
    result = response.json()["results"][0]
    page = api.get(f"/v1/kbs/default/types/{result['type_id']}/points", params={"limit": 1000})
    stored = {p["point_id"]: p for p in page.json()["points"]}
    assert stored[result["point_id"]]["x"] == point["x"]
    assert stored[result["point_id"]]["feasible"] is point["feasible"]


@pytest.mark.slow
@FUZZ
@given(data=st.data())
def test_bad_values_are_refused_and_change_nothing(api: TestClient, data: st.DataObject) -> None:
    graph = data.draw(graphs())
    good = data.draw(x_for(graph))
    bad = data.draw(bad_x(graph))
    before = snapshot(api)
    # The bad point shares its batch with a good one: the whole batch is refused.
    batch = [
        {"graph": graph, "x": good, "feasible": True},
        {"graph": graph, "x": bad, "feasible": False},
    ]
    response = api.post(
        POINTS, content=json.dumps({"points": batch}), headers={"content-type": "application/json"}
    )
    assert_refused(api, response, before)


@pytest.mark.slow
@FUZZ
@given(
    payload=st.recursive(
        st.none() | st.booleans() | st.floats() | st.text(max_size=20),
        lambda inner: (
            st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
        ),
        max_leaves=20,
    )
)
def test_arbitrary_json_never_breaks_a_route(api: TestClient, payload: Any) -> None:
    before = seed(api)
    body = json.dumps(payload)
    for path in (POINTS, "/v1/kbs/default/types/match", "/v1/kbs", "/v1/kbs/default/suggest"):
        response = api.post(path, content=body, headers={"content-type": "application/json"})
        assert_refused(api, response, before)


def post_raw(api: TestClient, body: dict[str, Any], sentinel: str = "") -> Any:
    """POST `body` as JSON with NaN/Infinity tokens as Python writes them; `sentinel`, if
    given, replaces the number 12345.0 in the text (to send a literal such as 1e999)."""
    text = json.dumps(body)
    if sentinel:
        text = text.replace("12345.0", sentinel)
    return api.post(POINTS, content=text, headers={"content-type": "application/json"})


def test_non_finite_numbers_are_refused(api: TestClient) -> None:
    before = seed(api)
    for value, sentinel in [(math.nan, ""), (math.inf, ""), (-math.inf, ""), (12345.0, "1e999")]:
        in_x = {"graph": BASE_GRAPH, "x": {"#dir": "top", "#pose": [0.5, value]}, "feasible": True}
        assert_refused(api, post_raw(api, {"points": [in_x]}, sentinel), before)
        graph = copy.deepcopy(BASE_GRAPH)
        graph["nodes"][2]["domain"]["high"] = [1.0, value]
        in_domain = {"graph": graph, "x": GOOD_X, "feasible": True}
        assert_refused(api, post_raw(api, {"points": [in_domain]}, sentinel), before)


def test_wrong_dimensions_and_unknown_labels_are_refused(api: TestClient) -> None:
    before = seed(api)
    cases = [
        {"#dir": "top", "#pose": [0.5]},
        {"#dir": "top", "#pose": [0.5, 0.5, 0.5]},
        {"#dir": "top", "#pose": []},
        {"#dir": "top", "#pose": [0.5, 1.5]},
        {"#dir": "sideways", "#pose": [0.5, 0.5]},
        {"#dir": ["top"], "#pose": [0.5, 0.5]},
        {"#dir": "top"},
        {"#dir": "top", "#pose": [0.5, 0.5], "#yaw": [0.1]},
        {"#pose": [0.5, 0.5], "dir": "top"},
    ]
    for x in cases:
        response = api.post(
            POINTS, json={"points": [{"graph": BASE_GRAPH, "x": x, "feasible": True}]}
        )
        assert_refused(api, response, before)
    match = api.post("/v1/kbs/default/types/match", json={"graphs": [BASE_GRAPH]}).json()
    type_id = match[0]["type_id"]
    predict = api.post(
        f"/v1/kbs/default/types/{type_id}/predict", json={"x": [{"#dir": "top", "#pose": [9.0]}]}
    )
    assert_refused(api, predict, before)


def test_huge_graphs_and_oversized_bodies_are_refused(api: TestClient) -> None:
    before = seed(api)
    many_nodes = copy.deepcopy(BASE_GRAPH)
    many_nodes["nodes"] += [
        {"id": f"c{i}", "role": "context", "label": f"box{i}"} for i in range(MAX_NODES)
    ]
    many_edges = copy.deepcopy(BASE_GRAPH)
    many_edges["edges"] = [
        {"source": "d", "target": "f", "label": f"e{i}"} for i in range(MAX_EDGES + 1)
    ]
    long_label = copy.deepcopy(BASE_GRAPH)
    long_label["nodes"][3]["label"] = "x" * 10_000
    for graph in (many_nodes, many_edges, long_label):
        response = api.post(
            POINTS, json={"points": [{"graph": graph, "x": GOOD_X, "feasible": True}]}
        )
        assert_refused(api, response, before)
    point = {"graph": BASE_GRAPH, "x": GOOD_X, "feasible": True}
    too_many = api.post(POINTS, json={"points": [point] * 1001})
    assert_refused(api, too_many, before)
    padding = {
        "graph": BASE_GRAPH,
        "x": GOOD_X,
        "feasible": True,
        "source": {"note": "z" * MAX_BODY_BYTES},
    }
    oversized = api.post(POINTS, json={"points": [padding]})
    assert oversized.status_code == 413
    assert snapshot(api) == before


def test_non_isomorphic_graph_under_one_hash_is_a_conflict(api: TestClient) -> None:
    """A 6-cycle and two triangles of identical links look the same to Weisfeiler-Lehman
    (every link has one link successor and the failure), but are different graphs."""

    def ring_graph(cycles: list[list[int]]) -> dict:
        nodes = [
            {"id": "f", "role": "failure", "label": "Plan-motion"},
            {"id": "d", "role": "decision", "label": "#pose", "domain": BOX},
        ] + [{"id": f"l{i}", "role": "connection", "label": "link"} for i in range(6)]
        edges = [{"source": "d", "target": "f", "label": "feeds"}]
        for cycle in cycles:
            for a, b in zip(cycle, cycle[1:] + cycle[:1], strict=True):
                edges.append({"source": f"l{a}", "target": f"l{b}", "label": "next"})
        edges += [{"source": f"l{i}", "target": "f", "label": "to"} for i in range(6)]
        return {"nodes": nodes, "edges": edges}

    hexagon = ring_graph([[0, 1, 2, 3, 4, 5]])
    triangles = ring_graph([[0, 1, 2], [3, 4, 5]])
    x = {"#pose": [0.5, 0.5]}
    first = api.post(POINTS, json={"points": [{"graph": hexagon, "x": x, "feasible": False}]})
    assert first.status_code == 201
    before = snapshot(api)
    match = api.post("/v1/kbs/default/types/match", json={"graphs": [triangles]})
    assert match.status_code == 409
    second = api.post(POINTS, json={"points": [{"graph": triangles, "x": x, "feasible": False}]})
    assert_refused(api, second, before)
    assert second.status_code == 409
    assert "isomorphic" in second.json()["detail"]


def test_same_hash_with_another_domain_is_a_conflict(api: TestClient) -> None:
    before = seed(api)
    wider = copy.deepcopy(BASE_GRAPH)
    wider["nodes"][2]["domain"] = {"kind": "continuous", "low": [0.0, 0.0], "high": [2.0, 2.0]}
    response = api.post(POINTS, json={"points": [{"graph": wider, "x": GOOD_X, "feasible": True}]})
    assert_refused(api, response, before)
    assert response.status_code == 409


def test_unknown_knowledge_bases_and_types_are_404(api: TestClient) -> None:
    before = seed(api)
    point = {"graph": BASE_GRAPH, "x": GOOD_X, "feasible": True}
    for method, path, body in [
        ("POST", "/v1/kbs/nope/points", {"points": [point]}),
        ("POST", "/v1/kbs/nope/types/match", {"graphs": [BASE_GRAPH]}),
        ("GET", "/v1/kbs/nope/types", None),
        ("DELETE", "/v1/kbs/nope", None),
        ("GET", "/v1/kbs/default/types/0123abcd", None),
        ("GET", "/v1/kbs/default/types/0123abcd/points", None),
        ("POST", "/v1/kbs/default/types/0123abcd/predict", {"x": [GOOD_X]}),
    ]:
        response = api.request(method, path, json=body)
        assert response.status_code == 404, (method, path, response.status_code, response.text)
        assert_refused(api, response, before)


def test_a_repeated_key_stores_nothing_twice(api: TestClient) -> None:
    before = seed(api)
    again = {"points": [{"graph": BASE_GRAPH, "x": GOOD_X, "feasible": False, "key": "seed-1"}]}
    response = api.post(POINTS, json=again)
    assert response.status_code in (200, 201)
    assert snapshot(api) == before

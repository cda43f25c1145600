"""The HTTP API against a real database, fresh per test, on SQLite and on PostgreSQL.

The core API: extension hooks (the surrogate engine) are off; the hook tests install their own."""

from __future__ import annotations

import json
from typing import Any

import pytest
from service_support import collision_pair, make_graph, make_point

from contract.models import SurrogateState


def post(client: Any, points: list[dict[str, Any]], kb: str = "default") -> Any:
    return client.post(f"/v1/kbs/{kb}/points", json={"points": points})


def n_points(client: Any, kb: str = "default") -> int:
    return next(k["n_points"] for k in client.get("/v1/kbs").json() if k["name"] == kb)


def test_health_names_the_database(core_client: Any, db_url: str) -> None:
    body = core_client.get("/healthz").json()
    assert body["status"] == "ok"
    assert body["database"] == db_url.split(":")[0].split("+")[0]


def test_default_kb_exists_and_kbs_are_created_listed_deleted(core_client: Any) -> None:
    assert [k["name"] for k in core_client.get("/v1/kbs").json()] == ["default"]
    created = core_client.post("/v1/kbs", json={"name": "lab-1"})
    assert created.status_code == 201 and created.json()["name"] == "lab-1"
    again = core_client.post("/v1/kbs", json={"name": "lab-1"})
    assert again.status_code == 409 and "already exists" in again.json()["detail"]
    assert core_client.post("/v1/kbs", json={"name": "no spaces"}).status_code == 422
    assert post(core_client, [make_point(1)], kb="lab-1").status_code == 201
    listed = {k["name"]: k for k in core_client.get("/v1/kbs").json()}
    assert listed["lab-1"]["n_types"] == 1 and listed["lab-1"]["n_points"] == 1
    assert core_client.delete("/v1/kbs/lab-1").status_code == 204
    assert core_client.delete("/v1/kbs/lab-1").status_code == 404
    assert core_client.get("/v1/kbs/lab-1/types").status_code == 404


def test_deleting_default_leaves_it_empty(core_client: Any) -> None:
    post(core_client, [make_point(1)])
    assert core_client.delete("/v1/kbs/default").status_code == 204
    assert core_client.get("/v1/kbs/default").json()["n_points"] == 0
    assert core_client.get("/v1/kbs/default/types").json() == []


def test_points_create_a_type_once_and_count(core_client: Any) -> None:
    first = post(core_client, [make_point(0, feasible=False)])
    assert first.status_code == 201
    (result,) = first.json()["results"]
    assert result["new_type"] is True
    batch = post(core_client, [make_point(i, feasible=i % 2 == 0) for i in range(1, 11)])
    results = batch.json()["results"]
    assert {r["type_id"] for r in results} == {result["type_id"]}
    assert not any(r["new_type"] for r in results)
    assert len({r["point_id"] for r in results}) == 10
    (summary,) = core_client.get("/v1/kbs/default/types").json()
    assert summary["type_id"] == result["type_id"]
    assert summary["n_points"] == 11 and summary["n_infeasible"] == 1 + 5
    assert summary["failure"] == "Inv-kin"
    assert summary["decisions"] == ["#dir", "#pose"] and summary["context"] == ["box1"]


def test_a_repeated_key_stores_nothing_and_replays_the_first_answer(core_client: Any) -> None:
    point = make_point(3, key="rollout-7-check-2")
    first = post(core_client, [point]).json()["results"][0]
    again = post(core_client, [point, point]).json()["results"]
    assert again == [first, first]
    assert first["new_type"] is True
    assert n_points(core_client) == 1
    # The key names that point: another one under it is refused (tests/server/test_idempotency).
    assert post(core_client, [make_point(4, key="rollout-7-check-2")]).status_code == 409


def test_points_without_key_are_each_stored(core_client: Any) -> None:
    results = post(core_client, [make_point(1, key=None), make_point(1, key=None)]).json()
    assert len({r["point_id"] for r in results["results"]}) == 2
    assert n_points(core_client) == 2


def test_node_ids_and_order_do_not_change_the_type(core_client: Any) -> None:
    graph = make_graph(context=("box1", "shelf"))
    renamed = make_graph(context=("box1", "shelf"), prefix="other-")
    renamed["nodes"].reverse()
    renamed["edges"].reverse()
    a = post(core_client, [make_point(1, graph=graph)]).json()["results"][0]
    b = post(core_client, [make_point(2, graph=renamed)]).json()["results"][0]
    assert a["type_id"] == b["type_id"] and b["new_type"] is False
    other = post(core_client, [make_point(1, graph=make_graph(context=("box2",)))]).json()
    assert other["results"][0]["type_id"] != a["type_id"]


def test_type_detail_has_graph_space_and_surrogate_state(core_client: Any) -> None:
    type_id = post(core_client, [make_point(1)]).json()["results"][0]["type_id"]
    detail = core_client.get(f"/v1/kbs/default/types/{type_id}").json()
    assert detail["space"]["#pose"]["low"] == [0.0, 0.0, -3.0]
    assert detail["space"]["#dir"]["choices"][2] == "top"
    assert {n["label"] for n in detail["graph"]["nodes"]} == {"Inv-kin", "#dir", "#pose", "box1"}
    assert [n["id"] for n in detail["graph"]["nodes"]] == ["n0", "n1", "n2", "n3"]
    assert "surrogate" in detail
    hooks = core_client.app.state.hooks
    hooks.surrogate_state = lambda kb, t: SurrogateState(status="fitted", n_fitted=1)
    shown = core_client.get(f"/v1/kbs/default/types/{type_id}").json()["surrogate"]
    assert shown["status"] == "fitted" and shown["n_fitted"] == 1

    def broken(kb: str, t: str) -> SurrogateState:
        raise RuntimeError("engine down")

    hooks.surrogate_state = broken
    response = core_client.get(f"/v1/kbs/default/types/{type_id}")
    assert response.status_code == 200 and response.json()["surrogate"] is None
    assert core_client.get("/v1/kbs/default/types/feedface").status_code == 404


def test_points_added_hook_gets_new_points_only(core_client: Any) -> None:
    calls: list[tuple[str, frozenset[str]]] = []
    core_client.app.state.hooks.points_added.append(lambda kb, ids: calls.append((kb, ids)))
    point = make_point(1)
    type_id = post(core_client, [point]).json()["results"][0]["type_id"]
    post(core_client, [point])
    assert calls == [("default", frozenset({type_id}))]


def test_domain_change_under_one_type_is_a_conflict(core_client: Any) -> None:
    post(core_client, [make_point(1)])
    wider = make_graph(pose_domain={"kind": "continuous", "low": [0, 0, -3], "high": [2, 1, 3]})
    response = post(core_client, [make_point(1, graph=wider), make_point(2)])
    assert response.status_code == 409
    assert "'#pose'" in response.json()["detail"]
    assert n_points(core_client) == 1
    match = core_client.post("/v1/kbs/default/types/match", json={"graphs": [wider]})
    assert match.status_code == 409


def test_a_hash_collision_is_a_conflict_not_a_merge(core_client: Any) -> None:
    """One 6-cycle vs two 3-cycles: Weisfeiler-Lehman cannot tell them apart."""
    six, two_threes = collision_pair()
    first = post(core_client, [{"graph": six, "x": {"#k": "a"}, "feasible": False}])
    assert first.status_code == 201
    second = post(core_client, [{"graph": two_threes, "x": {"#k": "a"}, "feasible": False}])
    assert second.status_code == 409
    assert "not isomorphic" in second.json()["detail"]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda p: p["x"].pop("#pose"), "x: missing value for decision '#pose'"),
        (lambda p: p["x"].update({"#extra": "top"}), "x.#extra"),
        (lambda p: p["x"].update({"#dir": "up"}), "x.#dir"),
        (lambda p: p["x"].update({"#pose": [0.5, 0.5]}), "x.#pose: expected 3 numbers"),
        (lambda p: p["x"].update({"#pose": [0.5, 1.5, 0.0]}), "x.#pose[1]"),
        (lambda p: p["x"].update({"#pose": "top"}), "x.#pose"),
        (lambda p: p["x"].update({"#dir": [0.1]}), "x.#dir"),
        (lambda p: p["graph"]["nodes"].pop(0), "graph.nodes: a causal graph has exactly one"),
        (lambda p: p["graph"]["nodes"][2].update(id="d"), "graph.nodes[2].id: duplicate"),
        (lambda p: p["graph"]["edges"][0].update(target="zz"), "graph.edges[0].target"),
        (lambda p: p["graph"]["nodes"][1].pop("domain"), "graph.nodes[1].domain"),
        (
            lambda p: p["graph"]["nodes"][3].update(
                domain={"kind": "categorical", "choices": ["a"]}
            ),
            "graph.nodes[3].domain: only decision",
        ),
        (lambda p: p["graph"]["nodes"][2].update(label="#dir"), "graph.nodes[2].label"),
        (lambda p: p["graph"]["edges"].append(dict(p["graph"]["edges"][0])), "graph.edges[3]"),
        (lambda p: p["graph"]["edges"].append({"source": "f", "target": "f"}), "graph.edges[3]"),
    ],
)
def test_bad_points_are_422_naming_the_field_and_store_nothing(
    core_client: Any, change: Any, field: str
) -> None:
    bad = make_point(5)
    change(bad)
    response = post(core_client, [make_point(1), bad])
    assert response.status_code == 422, response.text
    assert f"points[1].{field}" in response.json()["detail"]
    assert n_points(core_client) == 0


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_are_rejected(core_client: Any, number: str) -> None:
    point = json.dumps({"points": [make_point(1)]}).replace("0.1,", f"{number},", 1)
    assert number in point
    response = core_client.post(
        "/v1/kbs/default/points", content=point, headers={"content-type": "application/json"}
    )
    assert response.status_code == 422
    extra = make_point(1)
    extra["source"] = {"note": float("nan")}
    body = json.dumps({"points": [extra]})
    response = core_client.post(
        "/v1/kbs/default/points", content=body, headers={"content-type": "application/json"}
    )
    assert response.status_code == 422
    assert n_points(core_client) == 0


def test_limits_and_unknown_kb(core_client: Any) -> None:
    too_many = [make_point(i) for i in range(1001)]
    assert post(core_client, too_many).status_code == 422
    assert post(core_client, [make_point(1)], kb="nowhere").status_code == 404
    huge_rollout = make_point(1, rollout=2**70)
    response = post(core_client, [huge_rollout])
    assert response.status_code == 422 and "rollout" in response.json()["detail"]
    assert n_points(core_client) == 0


def test_a_batch_of_1000_is_one_post(core_client: Any) -> None:
    response = post(core_client, [make_point(i) for i in range(1000)])
    assert response.status_code == 201
    assert len({r["point_id"] for r in response.json()["results"]}) == 1000
    assert n_points(core_client) == 1000


def test_match_reports_existence_and_stores_nothing(core_client: Any) -> None:
    graph, other = make_graph(), make_graph(failure="Plan-motion")
    before = core_client.post("/v1/kbs/default/types/match", json={"graphs": [graph, other]})
    assert [r["exists"] for r in before.json()] == [False, False]
    assert core_client.get("/v1/kbs/default/types").json() == []
    post(core_client, [make_point(i, graph=graph) for i in range(3)])
    after = core_client.post("/v1/kbs/default/types/match", json={"graphs": [graph, other]}).json()
    assert [(r["exists"], r["n_points"]) for r in after] == [(True, 3), (False, 0)]
    assert after[0]["type_id"] == before.json()[0]["type_id"]


def test_points_page_with_provenance(core_client: Any) -> None:
    points = [
        make_point(i, task="desk", run="r1", rollout=i, worker="w0", time="2026-01-01T00:00:00Z")
        for i in range(25)
    ]
    points[0]["source"]["depth"] = 3
    type_id = post(core_client, points).json()["results"][0]["type_id"]
    seen, cursor, pages = [], None, 0
    while True:
        params = {"limit": 10, **({"cursor": cursor} if cursor else {})}
        page = core_client.get(f"/v1/kbs/default/types/{type_id}/points", params=params).json()
        seen.extend(page["points"])
        pages += 1
        cursor = page["next_cursor"]
        if cursor is None:
            break
    assert pages == 3 and len(seen) == 25
    assert [p["source"]["rollout"] for p in seen] == list(range(25))
    assert seen[0]["source"] == {
        "task": "desk",
        "run": "r1",
        "rollout": 0,
        "worker": "w0",
        "time": "2026-01-01T00:00:00Z",
        "depth": 3,
    }
    assert seen[3]["x"] == points[3]["x"] and seen[3]["key"] == points[3]["key"]
    bad = core_client.get(f"/v1/kbs/default/types/{type_id}/points", params={"cursor": "x1"})
    assert bad.status_code == 422


def test_csv_export_is_the_types_table(core_client: Any) -> None:
    points = [make_point(i, task="desk") for i in range(3)]
    type_id = post(core_client, points).json()["results"][0]["type_id"]
    response = core_client.get(f"/v1/kbs/default/types/{type_id}/points.csv")
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    lines = response.text.strip().splitlines()
    assert lines[0].startswith("point_id,feasible,#dir,#pose[0],#pose[1],#pose[2],task,")
    assert len(lines) == 4
    assert lines[2].split(",")[2:6] == ["right", "0.1", "0.14285714285714285", "-2.5"]
    assert core_client.get("/v1/kbs/default/types/nope/points.csv").status_code == 404


def test_training_points_for_the_surrogate(core_client: Any) -> None:
    from server.services.types import load_training_points

    type_id = post(core_client, [make_point(i) for i in range(6)]).json()["results"][0]["type_id"]
    store = core_client.app.state.store
    data = load_training_points(store, "default", type_id)
    assert data.version == 6 and len(data.x) == 6
    assert data.feasible == [i % 3 == 0 for i in range(6)]
    assert data.space["#pose"].high == [1.0, 1.0, 3.0]
    post(core_client, [make_point(i) for i in range(6, 8)])
    more = load_training_points(store, "default", type_id, after_point_id=data.last_point_id)
    assert len(more.x) == 2 and more.version == 8

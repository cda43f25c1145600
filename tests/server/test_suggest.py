"""POST /v1/kbs/{kb}/suggest over a real SQLite file and real gpytorch fits (in a thread)."""

from __future__ import annotations

from typing import Any

import pytest
from suggest_support import (
    SPACE,
    as_decision,
    clear_ok,
    make_client,
    points,
    post_points,
    reach_ok,
    suggest_body,
)

URL = "/v1/kbs/default/suggest"


def test_bad_requests_answer_a_clear_4xx(client: Any) -> None:
    reach, clear = post_points(client, 3)
    body = suggest_body([reach])

    def detail(request: dict[str, Any], status: int, url: str = URL) -> str:
        answer = client.post(url, json=request)
        assert answer.status_code == status, answer.text
        return answer.json()["detail"]

    assert "not found" in detail(suggest_body(["f" * 32]), 404)
    assert "not found" in detail(body, 404, "/v1/kbs/nope/suggest")
    unbound = suggest_body([reach])
    del unbound["constraints"][0]["bind"]["#pose"]
    assert "#pose" in detail(unbound, 422) and "not bound" in detail(unbound, 422)
    unknown = suggest_body([reach])
    unknown["constraints"][0]["bind"]["#grip"] = "d"
    assert "bind.#grip" in detail(unknown, 422)
    missing = suggest_body([reach])
    missing["constraints"][0]["bind"]["#pose"] = "q"
    assert "'q'" in detail(missing, 422)
    mismatch = suggest_body([clear])
    mismatch["space"] = {**SPACE, "p": {"kind": "continuous", "low": [0, 0], "high": [1, 1]}}
    assert detail(mismatch, 422).startswith("space.p")
    bad_fixed = suggest_body([clear], fixed={"d": "up"})
    assert detail(bad_fixed, 422).startswith("fixed.d")
    bad_exclude = suggest_body([clear], exclude=[{"d": "top", "p": [2.0, 0.0, 0.0]}])
    assert detail(bad_exclude, 422).startswith("exclude[0].p")
    every_dir = [{"d": d} for d in SPACE["d"]["choices"]]
    exhausted = suggest_body([clear], fixed={"p": [0.9, 0.1, 0.0]}, exclude=every_dir)
    exhausted["space"] = {"d": SPACE["d"]}
    assert "excluded" in detail(exhausted, 409)


def test_without_constraints_a_space_filling_point_away_from_exclude(client: Any) -> None:
    exclude = [{"d": d, "p": [0.1, 0.1, 0.0]} for d in SPACE["d"]["choices"]]
    answer = client.post(URL, json={"space": SPACE, "exclude": exclude, "seed": 1}).json()
    assert answer["method"] == "space-filling"
    assert max(answer["x"]["p"][:2]) > 0.3 or abs(answer["x"]["p"][2]) > 1.0


@pytest.mark.slow
def test_mpf_suggestions_land_in_both_constraints_once_fitted(client: Any) -> None:
    type_ids = post_points(client, 40)
    assert client.app.state.surrogates.wait_idle(timeout=300)
    state = client.get(f"/v1/kbs/default/types/{type_ids[0]}").json()["surrogate"]
    assert state["status"] == "ready" and state["n_fitted"] == 40 and state["kind"] == "vgp"
    assert len(state["lengthscales"]) == 8 and state["train_accuracy"] > 0.8
    feasible = 0
    for seed in range(5):
        answer = client.post(URL, json=suggest_body(type_ids, seed=seed)).json()
        assert answer["method"] == "mpf" and set(answer["p_feasible"]) == set(type_ids)
        x = as_decision(answer["x"])
        feasible += reach_ok(x) and clear_ok(x)
    assert feasible >= 4


@pytest.mark.slow
def test_fixed_variables_apply_and_exclude_is_respected(client: Any) -> None:
    type_ids = post_points(client, 30)
    assert client.app.state.surrogates.wait_idle(timeout=300)
    fixed = client.post(URL, json=suggest_body(type_ids, fixed={"d": "left"}, seed=0)).json()
    assert fixed["x"]["d"] == "left"
    first = client.post(URL, json=suggest_body(type_ids, seed=2)).json()["x"]
    again = client.post(URL, json=suggest_body(type_ids, seed=2, exclude=[first])).json()["x"]
    assert again != first


@pytest.mark.slow
def test_pending_suggestions_push_concurrent_planners_apart(sqlite_url: str) -> None:
    with make_client(sqlite_url) as client:
        type_ids = post_points(client, 30)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        first = client.post(URL, json=suggest_body(type_ids, seed=4)).json()
        second = client.post(URL, json=suggest_body(type_ids, seed=4)).json()
        assert first["n_pending"] == 0 and second["n_pending"] == 1
        assert second["x"] != first["x"]
        answer = [
            {"graph": g, "x": as_decision(first["x"]), "feasible": True}
            for g in (points(1)[0]["graph"], points(1)[1]["graph"])
        ]
        assert client.post("/v1/kbs/default/points", json={"points": answer}).status_code == 201
        assert client.app.state.surrogates.wait_idle(timeout=300)
        assert client.app.state.surrogates.pending.count("default") == 1


@pytest.mark.slow
def test_a_seed_reproduces_the_suggestion_for_a_given_model_state(sqlite_url: str) -> None:
    with make_client(sqlite_url, pending_ttl_s=0) as client:
        type_ids = post_points(client, 12)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        body = suggest_body(type_ids, seed=9)
        assert client.post(URL, json=body).json() == client.post(URL, json=body).json()


@pytest.mark.slow
def test_lookahead_picks_a_choice_that_a_feasible_continuation_can_follow(
    sqlite_url: str,
) -> None:
    """Of the untried grasps `top` and `left`, only `left` has a pose clear of box1 after it."""
    with make_client(sqlite_url) as client:
        type_ids = post_points(client, 40)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        tried = [{"d": d} for d in SPACE["d"]["choices"] if d not in ("top", "left")]
        for seed in range(4):
            body = suggest_body(type_ids, exclude=tried, lookahead=["p"], seed=seed)
            answer = client.post(URL, json=body).json()
            assert answer["x"]["d"] == "left" and set(answer["x"]) == {"d", "p"}
        pending = client.app.state.surrogates.pending.for_request("default", frozenset(type_ids))
        assert pending and all(set(x) == {"d"} for x in pending)
        for bad in (["q"], ["d", "p"]):
            answer = client.post(URL, json=suggest_body(type_ids, lookahead=bad))
            assert answer.status_code == 422 and "lookahead" in answer.text


@pytest.mark.slow
def test_a_batch_is_spread_distinct_and_pending(sqlite_url: str) -> None:
    with make_client(sqlite_url, pending_ttl_s=0) as client:
        type_ids = post_points(client, 40)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        single = client.post(URL, json=suggest_body(type_ids, seed=3)).json()
        assert single["batch"] == []
        answer = client.post(URL, json=suggest_body(type_ids, seed=3, n=4)).json()
        batch = answer["batch"]
        assert len(batch) == 4 and batch[0]["x"] == answer["x"] == single["x"]
        assert len({str(point["x"]) for point in batch}) == 4
        assert all(point["mpf"] == min(point["p_feasible"].values()) for point in batch)
        feasible = [reach_ok(as_decision(p["x"])) and clear_ok(as_decision(p["x"])) for p in batch]
        assert sum(feasible) >= 3
        too_many = client.post(URL, json=suggest_body(type_ids, n=1000))
        assert too_many.status_code == 422 and "n" in too_many.text
    with make_client(sqlite_url) as client:
        client.post(URL, json=suggest_body(type_ids, seed=3, n=4))
        assert client.app.state.surrogates.pending.count("default") == 4


@pytest.mark.slow
def test_a_batch_over_lookahead_differs_in_the_node_variable(sqlite_url: str) -> None:
    with make_client(sqlite_url) as client:
        type_ids = post_points(client, 30)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        body = suggest_body(type_ids, lookahead=["p"], seed=1, n=3)
        batch = client.post(URL, json=body).json()["batch"]
        assert len({point["x"]["d"] for point in batch}) == 3

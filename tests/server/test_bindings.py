"""/v1/kbs/{kb}/bindings: found binding lists, stored and read after a cursor, on both backends."""

from __future__ import annotations

from typing import Any

import pytest

BINDINGS = "/v1/kbs/default/bindings"
DESK, PACK = "a" * 64, "b" * 64


def found(skeleton: str = DESK, run: str | None = "a", **extra: Any) -> dict[str, Any]:
    body = {
        "task": "desk",
        "skeleton": skeleton,
        "run": run,
        "rollout": 12,
        "bindings": {"#dir1": "front", "#pose12": [0.2, 0.8, 0.5]},
    }
    return body | extra


def post(client: Any, body: dict[str, Any]) -> dict[str, Any]:
    response = client.post(BINDINGS, json=body)
    assert response.status_code == 201, response.text
    return response.json()


def listed(client: Any, **params: Any) -> dict[str, Any]:
    response = client.get(BINDINGS, params=params)
    assert response.status_code == 200, response.text
    return response.json()


def test_bindings_of_one_skeleton_after_a_cursor_without_a_runs_own(core_client: Any) -> None:
    first = post(core_client, found())
    assert first["bindings"] == found()["bindings"] and first["rollout"] == 12
    start = listed(core_client, skeleton=DESK)
    assert [b["binding_id"] for b in start["bindings"]] == [first["binding_id"]]
    cursor = start["cursor"]
    assert cursor == first["binding_id"]

    post(core_client, found(run="b", task="pack", skeleton=PACK))
    mine = post(core_client, found(run="a"))
    theirs = post(core_client, found(run="b", bindings={"#dir1": "top", "#pose12": [0.1]}))
    answer = listed(core_client, skeleton=DESK, after=cursor, exclude_run="a")
    assert [b["binding_id"] for b in answer["bindings"]] == [theirs["binding_id"]]
    assert answer["bindings"][0]["bindings"] == {"#dir1": "top", "#pose12": [0.1]}
    assert answer["cursor"] >= theirs["binding_id"] > mine["binding_id"]
    assert listed(core_client, skeleton=DESK, after=answer["cursor"])["bindings"] == []
    assert len(listed(core_client)["bindings"]) == 4


def test_a_limit_cuts_the_answer_at_a_cursor_that_resumes_it(core_client: Any) -> None:
    ids = [post(core_client, found(rollout=i))["binding_id"] for i in range(5)]
    seen, cursor = [], None
    for _ in range(5):
        page = listed(core_client, limit=2, **({} if cursor is None else {"after": cursor}))
        seen += [b["binding_id"] for b in page["bindings"]]
        if cursor == page["cursor"]:
            break
        cursor = page["cursor"]
    assert seen == ids


def test_deleting_the_knowledge_base_deletes_its_bindings(core_client: Any) -> None:
    assert core_client.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    response = core_client.post("/v1/kbs/lab/bindings", json=found())
    assert response.status_code == 201, response.text
    assert core_client.delete("/v1/kbs/lab").status_code == 204
    assert core_client.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    assert core_client.get("/v1/kbs/lab/bindings").json()["bindings"] == []


@pytest.mark.parametrize(
    "body",
    [
        found(bindings={}),
        found(skeleton=""),
        found(rollout=-1),
        found(bindings={"#dir1": {"nested": 1}}),
        found(task=None),
        found(surprise=1),
    ],
)
def test_bad_input_is_a_clear_422(core_client: Any, body: dict[str, Any]) -> None:
    response = core_client.post(BINDINGS, json=body)
    assert response.status_code == 422, response.text
    assert response.json()["detail"]


@pytest.mark.parametrize("params", [{"after": -1}, {"limit": 0}, {"limit": 101}])
def test_bad_parameters_are_a_clear_422(core_client: Any, params: dict[str, Any]) -> None:
    response = core_client.get(BINDINGS, params=params)
    assert response.status_code == 422, response.text


def test_an_unknown_knowledge_base_is_a_404(core_client: Any) -> None:
    assert core_client.get("/v1/kbs/nowhere/bindings").status_code == 404
    assert core_client.post("/v1/kbs/nowhere/bindings", json=found()).status_code == 404

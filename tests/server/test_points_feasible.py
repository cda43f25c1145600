"""POST /v1/kbs/{kb}/points/feasible: the newest feasible points per type, on both backends."""

from __future__ import annotations

from typing import Any

import pytest
from service_support import make_graph, make_point

POINTS = "/v1/kbs/default/points"
FEASIBLE = "/v1/kbs/default/points/feasible"


def post(client: Any, points: list[dict[str, Any]]) -> list[dict[str, Any]]:
    response = client.post(POINTS, json={"points": points})
    assert response.status_code == 201, response.text
    return response.json()["results"]


def test_the_newest_feasible_points_of_each_type_with_their_run_and_rollout(
    core_client: Any,
) -> None:
    place, grasp = make_graph(), make_graph(context=("box2",))
    placed = post(
        core_client,
        [make_point(i, graph=place, feasible=i != 3, run="a", rollout=i) for i in range(5)],
    )
    grasped = post(core_client, [make_point(9, graph=grasp, feasible=True, run="b", rollout=7)])
    post(core_client, [make_point(10, graph=make_graph("Collide"), feasible=True)])
    place_id, grasp_id = placed[0]["type_id"], grasped[0]["type_id"]

    response = core_client.post(
        FEASIBLE, json={"type_ids": [place_id, grasp_id, "0" * 64], "per_type": 2}
    )
    assert response.status_code == 200, response.text
    points = response.json()["points"]
    by_type = {t: [p for p in points if p["type_id"] == t] for t in (place_id, grasp_id)}
    # Rollout 3 failed: the newest two feasible ones are rollouts 4 and 2, the newest first.
    assert [p["rollout"] for p in by_type[place_id]] == [4, 2]
    assert [p["point_id"] for p in by_type[place_id]] == [
        placed[4]["point_id"],
        placed[2]["point_id"],
    ]
    assert all(p["feasible"] and p["run"] == "a" for p in by_type[place_id])
    assert by_type[place_id][0]["x"] == make_point(4, graph=place)["x"]
    assert [(p["run"], p["rollout"]) for p in by_type[grasp_id]] == [("b", 7)]
    assert len(points) == 3  # the unknown type has none, the unasked one is left out


@pytest.mark.parametrize(
    "body",
    [
        {"type_ids": ["t"], "per_type": 0},
        {"type_ids": ["t"], "per_type": 101},
        {"type_ids": "t"},
        {"type_ids": ["t"] * 513},
        {"type_ids": ["t"], "limit": 3},
        {},
    ],
)
def test_bad_input_is_a_clear_422(core_client: Any, body: dict[str, Any]) -> None:
    response = core_client.post(FEASIBLE, json=body)
    assert response.status_code == 422, response.text
    assert response.json()["detail"]


def test_an_unknown_knowledge_base_is_a_404(core_client: Any) -> None:
    response = core_client.post("/v1/kbs/nowhere/points/feasible", json={"type_ids": []})
    assert response.status_code == 404, response.text

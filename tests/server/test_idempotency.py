"""An idempotency key names one request: the same point again is a replay, a different point
under the key is a 409 that stores nothing (no point, no empty type), on both backends."""

from __future__ import annotations

from typing import Any

from service_support import make_graph, make_point
from sqlalchemy import update

from server.db import Store
from server.orm import PointRow

POINTS = "/v1/kbs/default/points"


def post(client: Any, *points: dict[str, Any]) -> Any:
    return client.post(POINTS, json={"points": list(points)})


def stored(client: Any) -> tuple[int, int]:
    """(types, points) of the default knowledge base."""
    kb = client.get("/v1/kbs/default").json()
    return kb["n_types"], kb["n_points"]


def test_the_same_point_under_its_key_is_a_replay(core_client: Any) -> None:
    source = {"task": "desk", "note": {"a": [1, 2]}}
    point = make_point(1, key="k-1", **source)
    first = post(core_client, point)
    assert first.status_code == 201
    again = post(core_client, point)
    assert again.status_code == 201
    assert again.json() == first.json()
    renamed = make_point(1, key="k-1", graph=make_graph(prefix="n-"), **source)
    assert post(core_client, renamed).json() == first.json(), "node ids do not make a new point"
    assert stored(core_client) == (1, 1)


def test_a_different_point_under_a_used_key_is_409_and_stores_nothing(core_client: Any) -> None:
    assert post(core_client, make_point(1, key="k-1")).status_code == 201
    before = stored(core_client)
    other_x = make_point(2, key="k-1")
    other_label = make_point(1, key="k-1", feasible=not make_point(1)["feasible"])
    other_source = make_point(1, key="k-1", task="pack")
    new_type = make_point(1, key="k-1", graph=make_graph("Plan-motion"))
    for point in (other_x, other_label, other_source, new_type):
        response = post(core_client, make_point(5), point)
        assert response.status_code == 409, response.text
        assert "idempotency key" in response.json()["detail"]
        assert stored(core_client) == before, "a refused post left a point or an empty type"


def test_one_key_twice_in_a_batch_must_name_one_point(core_client: Any) -> None:
    twice = post(core_client, make_point(1, key="k-2"), make_point(1, key="k-2"))
    assert twice.status_code == 201
    results = twice.json()["results"]
    assert results[0] == results[1]
    clash = post(core_client, make_point(1, key="k-3"), make_point(2, key="k-3"))
    assert clash.status_code == 409
    assert stored(core_client) == (1, 1)


def test_a_point_stored_without_a_payload_hash_replays_for_any_payload(
    core_client: Any, db_url: str
) -> None:
    first = post(core_client, make_point(1, key="old"))
    store = Store.from_url(db_url)
    try:
        with store.transaction(write=True) as session:
            session.execute(update(PointRow).values(payload_hash=None))
    finally:
        store.dispose()
    again = post(core_client, make_point(2, key="old"))
    assert again.status_code == 201
    assert again.json() == first.json()
    assert stored(core_client) == (1, 1)

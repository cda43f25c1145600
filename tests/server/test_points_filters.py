"""Listing a type's points with filters, the whole base as one CSV, formula-safe CSV cells and
the 422 for a query parameter a route does not take (issue 56.6, issue 55.7)."""

from __future__ import annotations

import csv
import io
import json
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from tests.service_support import make_graph, make_point


def _stock(client: Any) -> dict[str, str]:
    blocked = make_graph("Inv-kin", ("box1",))
    shelf = make_graph("Plan-motion", ("shelf",))
    points = [
        make_point(
            i,
            graph=blocked,
            task="desk" if i < 6 else "deskP",
            run=f"run-{i % 2}",
            worker=f"w{i % 3}",
        )
        for i in range(9)
    ]
    points.append(make_point(0, graph=shelf, task="=HYPERLINK(1)", run="-1", worker="@w"))
    response = client.post("/v1/kbs/default/points", json={"points": points})
    assert response.status_code == 201, response.text
    results = response.json()["results"]
    return {"blocked": results[0]["type_id"], "shelf": results[-1]["type_id"]}


def _listed(client: Any, type_id: str, **params: Any) -> list[dict[str, Any]]:
    response = client.get(f"/v1/kbs/default/types/{type_id}/points", params=params)
    assert response.status_code == 200, response.text
    return response.json()["points"]


def test_points_listing_filters_by_label_provenance_and_time(core_client: Any) -> None:
    ids = _stock(core_client)
    blocked = ids["blocked"]
    every = _listed(core_client, blocked)
    assert len(every) == 9
    infeasible = _listed(core_client, blocked, feasible="false")
    assert infeasible and all(not p["feasible"] for p in infeasible)
    assert len(infeasible) == sum(not p["feasible"] for p in every)
    assert all(p["feasible"] for p in _listed(core_client, blocked, feasible="true"))
    assert {p["source"]["task"] for p in _listed(core_client, blocked, task="deskP")} == {"deskP"}
    assert len(_listed(core_client, blocked, run="run-1")) == 4
    assert len(_listed(core_client, blocked, worker="w0", task="desk")) == 2
    stored = datetime.fromisoformat(every[0]["created_at"])
    later = (stored + timedelta(hours=1)).isoformat()
    earlier = (stored - timedelta(hours=1)).isoformat()
    assert _listed(core_client, blocked, since=later) == []
    assert len(_listed(core_client, blocked, since=earlier, until=later)) == 9
    # a time without a zone is UTC
    naive = (stored.astimezone(UTC) + timedelta(hours=1)).replace(tzinfo=None).isoformat()
    assert len(_listed(core_client, blocked, until=naive)) == 9
    # the cursor pages a filtered listing
    first = core_client.get(
        f"/v1/kbs/default/types/{blocked}/points", params={"run": "run-0", "limit": 2}
    ).json()
    rest = _listed(core_client, blocked, run="run-0", cursor=first["next_cursor"])
    assert [p["source"]["run"] for p in first["points"] + rest] == ["run-0"] * 5


@pytest.mark.parametrize(
    "params",
    [
        {"feasible": "maybe"},
        {"since": "yesterday"},
        {"since": "2030-01-02T00:00:00", "until": "2030-01-01T00:00:00"},
        {"feasable": "false"},
        {"task": "desk", "runs": "run-1"},
    ],
)
def test_bad_or_unknown_filters_are_422(core_client: Any, params: dict[str, str]) -> None:
    blocked = _stock(core_client)["blocked"]
    response = core_client.get(f"/v1/kbs/default/types/{blocked}/points", params=params)
    assert response.status_code == 422, response.text
    if "feasable" in params or "runs" in params:
        assert "unknown query parameter" in response.json()["detail"]


@pytest.mark.parametrize(
    "path",
    [
        "/v1/kbs",
        "/v1/kbs/default/types",
        "/healthz",
        "/v1/kbs/default/points.csv",
        "/ui/api/overview",
    ],
)
def test_an_unknown_query_parameter_is_422_across_the_api(core_client: Any, path: str) -> None:
    assert core_client.get(path).status_code == 200
    response = core_client.get(path, params={"bogus": "1"})
    assert response.status_code == 422
    assert "'bogus'" in response.json()["detail"]


def test_the_whole_base_is_one_csv_with_formula_cells_quoted(core_client: Any) -> None:
    ids = _stock(core_client)
    response = core_client.get("/v1/kbs/default/points.csv")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert len(rows) == 10
    assert {r["type_id"] for r in rows} == set(ids.values())
    assert [int(r["point_id"]) for r in rows] == sorted(int(r["point_id"]) for r in rows)
    assert json.loads(rows[0]["x"])["#dir"] == "top" or "#pose" in json.loads(rows[0]["x"])
    shelf = next(r for r in rows if r["type_id"] == ids["shelf"])
    assert shelf["task"] == "'=HYPERLINK(1)"
    assert shelf["run"] == "'-1" and shelf["worker"] == "'@w"
    only = core_client.get("/v1/kbs/default/points.csv", params={"task": "desk", "feasible": True})
    picked = list(csv.DictReader(io.StringIO(only.text)))
    assert picked and all(r["task"] == "desk" and r["feasible"] == "1" for r in picked)
    assert core_client.get("/v1/kbs/nowhere/points.csv").status_code == 404


def test_a_type_csv_quotes_formula_cells_and_keeps_negative_numbers(core_client: Any) -> None:
    ids = _stock(core_client)
    text = core_client.get(f"/v1/kbs/default/types/{ids['shelf']}/points.csv").text
    row = next(csv.DictReader(io.StringIO(text)))
    assert row["task"] == "'=HYPERLINK(1)" and row["worker"] == "'@w"
    assert row["#pose[2]"] == "-3.0"  # a number is never quoted

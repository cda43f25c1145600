"""What optuna-dashboard users expect (issue 56.5): parallel coordinates of a type's points, a
compare view (one type across tasks; two knowledge bases), a run filter in the points table."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from typing import Any

import pytest

from tests.service_support import make_graph, make_point

SVG_NS = "{http://www.w3.org/2000/svg}"


@pytest.fixture
def stocked(core_client: Any) -> dict[str, Any]:
    graph = make_graph("Inv-kin", ("box1",))
    shelf = make_graph("Plan-motion", ("shelf",))

    def post(kb: str, points: list[dict[str, Any]]) -> str:
        response = core_client.post(f"/v1/kbs/{kb}/points", json={"points": points})
        assert response.status_code == 201, response.text
        return response.json()["results"][0]["type_id"]

    points = [
        make_point(i, graph=graph, task="desk" if i < 8 else "pack", run=f"run-{i % 3}")
        for i in range(12)
    ]
    type_id = post("default", points)
    shelf_id = post("default", [make_point(0, graph=shelf)])
    assert core_client.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    post("lab", [make_point(i, graph=graph, feasible=True) for i in range(3)])
    return {"client": core_client, "type_id": type_id, "shelf": shelf_id}


def test_parallel_coordinates_draw_a_line_per_point_over_every_decision(
    stocked: dict[str, Any],
) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    svg = client.get(f"/ui/kbs/default/types/{type_id}/parallel.svg")
    assert svg.status_code == 200
    root = ET.fromstring(svg.text)
    lines = [e for e in root.iter(f"{SVG_NS}polyline") if e.get("class") == "cp-parallel-line"]
    assert len(lines) == 12
    assert {line.get("data-feasible") for line in lines} == {"0", "1"}
    axes = [g.get("data-dim") for g in root.iter(f"{SVG_NS}g") if g.get("data-dim")]
    assert sorted(axes) == ["#dir", "#pose[0]", "#pose[1]", "#pose[2]"]
    assert all(len(line.get("points").split()) == 4 for line in lines)
    # infeasible lines first, so that the feasible ones are drawn on top
    flags = [line.get("data-feasible") for line in lines]
    assert flags == sorted(flags)
    narrow = ET.fromstring(
        client.get(f"/ui/kbs/default/types/{type_id}/parallel.svg", params={"cols": 2}).text
    )
    assert float(narrow.get("width")) < float(root.get("width"))
    assert f"/types/{type_id}/parallel.svg" in client.get(f"/ui/kbs/default/types/{type_id}").text


def test_a_type_compared_across_its_tasks(stocked: dict[str, Any]) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    panel = client.get(f"/ui/api/kbs/default/types/{type_id}").json()["fragments"]["tasks-panel"]
    rows = re.findall(r"<tr><td>(\w+)</td><td class=\"num\">(\d+)</td>", panel)
    assert rows == [("desk", "8"), ("pack", "4")]
    # desk: i < 8 feasible where i % 3 == 0 -> 0, 3, 6
    assert "38%" in panel


def test_two_knowledge_bases_side_by_side(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    page = client.get("/ui/compare", params={"a": "default", "b": "lab"})
    assert page.status_code == 200
    html = page.text
    both = re.search(rf'<tr data-type-id="{stocked["type_id"]}">(.*?)</tr>', html, re.S)
    assert both, "the shared type has no row"
    assert ">12<" in both.group(1) and ">3<" in both.group(1) and "100%" in both.group(1)
    assert "+67 pts" in both.group(1)  # 4 of 12 feasible in default, 3 of 3 in lab
    only = re.search(rf'<tr data-type-id="{stocked["shelf"]}">(.*?)</tr>', html, re.S)
    assert only and "not in lab" in only.group(1)
    assert 'id="compare-form"' in client.get("/", params={"kb": "default"}).text
    missing = client.get("/ui/compare", params={"a": "default", "b": "nope"})
    assert missing.status_code == 404 and "nope" in missing.text
    assert client.get("/ui/compare", params={"a": "default"}).status_code == 422


def test_the_points_table_filters_by_run_and_sorts(stocked: dict[str, Any]) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    html = client.get(f"/ui/kbs/default/types/{type_id}", params={"run": "run-1"}).text
    rows = re.findall(r'<tr class="[a-z ]+" data-point-id="(\d+)">', html)
    assert len(rows) == 4 and "4 of 12 points match" in html
    assert 'name="run" list="run-names" value="run-1"' in html
    assert '<table id="points-table" class="sortable">' in html

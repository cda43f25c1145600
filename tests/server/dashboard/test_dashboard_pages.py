"""The dashboard's pages and JSON over a real database holding points posted through the API."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from typing import Any

import pytest

from tests.service_support import make_graph, make_point

SVG_NS = "{http://www.w3.org/2000/svg}"


def _post(client: Any, kb: str, points: list[dict[str, Any]]) -> list[dict[str, Any]]:
    response = client.post(f"/v1/kbs/{kb}/points", json={"points": points})
    assert response.status_code == 201, response.text
    return response.json()["results"]


@pytest.fixture
def stocked(app_client: Any) -> dict[str, Any]:
    """Two types in `default` (27 and 4 points, from two tasks and three workers), one in `lab`."""
    blocked = make_graph("Inv-kin", ("box1",))
    shelf = make_graph("Plan-motion", ("shelf",))
    points = [
        make_point(
            i,
            graph=blocked,
            task="desk" if i < 20 else "deskP",
            run=f"run-{i % 3}",
            rollout=i,
            worker=f"worker-{i % 2}",
        )
        for i in range(27)
    ]
    points += [
        make_point(i, graph=shelf, task="regrasp", run="run-9", worker="worker-9") for i in range(4)
    ]
    results = _post(app_client, "default", points)
    assert app_client.post("/v1/kbs", json={"name": "lab"}).status_code == 201
    _post(app_client, "lab", [make_point(0, graph=blocked, worker="lab-worker")])
    return {"client": app_client, "blocked": results[0]["type_id"], "shelf": results[-1]["type_id"]}


def _rows(html: str, tbody_id: str) -> list[str]:
    body = re.search(rf'<tbody id="{tbody_id}">(.*?)</tbody>', html, re.S)
    assert body, f"no tbody {tbody_id}"
    return re.findall(r"<tr[^>]*>.*?</tr>", body.group(1), re.S)


def test_overview_lists_bases_types_with_provenance_and_workers(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    page = client.get("/")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    html = page.text
    kb_rows = _rows(html, "kbs-rows")
    assert len(kb_rows) == 2 and "default" in kb_rows[0] and "lab" in kb_rows[1]
    types = {r: r for r in _rows(html, "types-rows")}
    assert len(types) == 2
    blocked = next(r for r in types if stocked["blocked"] in r)
    assert ">27<" in blocked and "Inv-kin" in blocked and "box1" in blocked
    # make_point labels i % 3 == 0 feasible: 9 of 27
    assert "33%" in blocked
    assert "desk <small>(20)</small>" in blocked and "deskP <small>(7)</small>" in blocked
    assert f"/ui/kbs/default/types/{stocked['blocked']}" in blocked
    workers = _rows(html, "workers-rows")
    names = {re.search(r"<td>(.*?)</td>", row).group(1) for row in workers}
    assert names == {"worker-0", "worker-1", "worker-9", "lab-worker"}
    assert 'data-poll="/ui/api/overview?kb=default"' in html


def test_overview_of_another_base_and_of_an_unknown_one(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    lab = client.get("/?kb=lab").text
    assert len(_rows(lab, "types-rows")) == 1
    missing = client.get("/?kb=nope")
    assert missing.status_code == 404 and "nope" in missing.text
    assert client.get("/ui/api/overview?kb=nope").status_code == 404


def test_overview_json_carries_data_and_the_fragments_the_page_swaps_in(
    stocked: dict[str, Any],
) -> None:
    client = stocked["client"]
    before = client.get("/ui/api/overview").json()
    assert before["kb"] == "default"
    assert {t["type_id"]: t["n_points"] for t in before["types"]}[stocked["blocked"]] == 27
    assert set(before["fragments"]) == {"kbs-rows", "types-rows", "workers-rows"}
    _post(
        client,
        "default",
        [
            make_point(100 + i, graph=make_graph("Inv-kin", ("box1",)), worker="late-worker")
            for i in range(3)
        ],
    )
    after = client.get("/ui/api/overview").json()
    assert {t["type_id"]: t["n_points"] for t in after["types"]}[stocked["blocked"]] == 30
    assert after["workers"][0]["worker"] == "late-worker"
    assert "late-worker" in after["fragments"]["workers-rows"]


def test_type_page_shows_graph_heat_map_surrogate_and_a_page_of_points(
    stocked: dict[str, Any],
) -> None:
    client = stocked["client"]
    type_id = stocked["blocked"]
    page = client.get(f"/ui/kbs/default/types/{type_id}?limit=10")
    assert page.status_code == 200
    html = page.text
    graph = ET.fromstring(re.search(r'<svg class="cp-graph".*?</svg>', html, re.S).group(0))
    roles = sorted(g.get("data-role") for g in graph.iter(f"{SVG_NS}g"))
    assert roles == ["context", "decision", "decision", "failure"]
    heatmap = ET.fromstring(re.search(r'<svg class="cp-heatmap".*?</svg>', html, re.S).group(0))
    panels = [g.get("data-panel") for g in heatmap.iter(f"{SVG_NS}g") if g.get("data-panel")]
    assert panels == [f"#dir={d}" for d in ("front", "right", "top", "back", "left")]
    marks = [e for e in heatmap.iter() if e.get("class") == "cp-observed"]
    assert len(marks) == 27  # every stored point drawn
    assert 'id="surrogate-panel"' in html and 'id="provenance-panel"' in html
    rows = re.findall(r'<tr class="(?:feasible|infeasible)">', html)
    assert len(rows) == 10
    next_link = re.search(r'id="next-page" href="\?cursor=(\d+)&amp;limit=10', html)
    assert next_link
    second = client.get(f"/ui/kbs/default/types/{type_id}?limit=10&cursor={next_link.group(1)}")
    first_ids = re.findall(r'<td class="num">(\d+)</td>\s*<td>(?:in)?feasible', html)
    second_ids = re.findall(r'<td class="num">(\d+)</td>\s*<td>(?:in)?feasible', second.text)
    assert len(first_ids) == len(second_ids) == 10
    assert not set(first_ids) & set(second_ids)
    assert min(map(int, second_ids)) > max(map(int, first_ids))


def test_heat_map_axes_can_be_chosen(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    url = f"/ui/kbs/default/types/{stocked['blocked']}/heatmap.svg"
    svg = client.get(url, params={"x": "#pose[2]", "y": "#pose[0]", "n": 8})
    assert svg.status_code == 200 and svg.headers["content-type"] == "image/svg+xml"
    root = ET.fromstring(svg.text)
    labels = {t.text for t in root.iter(f"{SVG_NS}text")}
    assert {"#pose[2]", "#pose[0]"} <= labels and "#pose[1]" not in labels
    cells = [r for r in root.iter(f"{SVG_NS}rect") if r.find(f"{SVG_NS}title") is not None]
    assert len(cells) == 5 * 8 * 8
    assert client.get(url, params={"n": 1000}).status_code == 422


def test_type_json_follows_new_points(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    url = f"/ui/api/kbs/default/types/{stocked['shelf']}"
    before = client.get(url).json()
    assert before["n_points"] == 4
    assert set(before["fragments"]) == {"stats-panel", "provenance-panel", "surrogate-panel"}
    _post(client, "default", [make_point(7, graph=make_graph("Plan-motion", ("shelf",)))])
    after = client.get(url).json()
    assert after["n_points"] == 5 and after["heatmap_key"] != before["heatmap_key"]
    assert '<dd id="n-points">5</dd>' in after["fragments"]["stats-panel"]


def test_unknown_things_are_clear_404s(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    page = client.get("/ui/kbs/default/types/0123abcd")
    assert page.status_code == 404 and "0123abcd" in page.text
    assert page.headers["content-type"].startswith("text/html")
    assert client.get("/ui/kbs/nope/types/0123abcd").status_code == 404
    assert client.get("/ui/api/kbs/default/types/0123abcd").status_code == 404
    assert client.get("/ui/kbs/default/types/0123abcd/graph.svg").status_code == 404
    assert client.get("/ui/static/../app.py").status_code == 404
    assert client.get("/ui/static/nothing.js").status_code == 404


def test_static_script_and_graph_image_are_served(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    script = client.get("/ui/static/dashboard.js")
    assert script.status_code == 200
    assert script.headers["content-type"].startswith("text/javascript")
    assert "fetch(" in script.text
    assert client.get("/ui/static/dashboard.css").headers["content-type"].startswith("text/css")
    graph = client.get(f"/ui/kbs/default/types/{stocked['blocked']}/graph.svg")
    assert graph.headers["content-type"] == "image/svg+xml"
    ET.fromstring(graph.text)


def test_empty_service_shows_empty_tables(app_client: Any) -> None:
    html = app_client.get("/").text
    assert "no CP type in this knowledge base yet" in html
    assert "no worker has posted points" in html

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


def _point_ids(html: str) -> list[int]:
    return [
        int(i)
        for i in re.findall(r'<tr class="(?:in)?feasible(?: held)?" data-point-id="(\d+)">', html)
    ]


def _link(html: str, link_id: str) -> str | None:
    found = re.search(rf'id="{link_id}" href="([^"]+)"', html)
    return found.group(1).replace("&amp;", "&") if found else None


def test_points_table_filters_by_label_and_task(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    base = f"/ui/kbs/default/types/{stocked['blocked']}"
    html = client.get(base, params={"feasible": "false", "task": "desk"}).text
    ids = _point_ids(html)
    # desk is i < 20, feasible is i % 3 == 0: 13 infeasible desk points
    assert len(ids) == 13 and "13 of 27 points match" in html
    assert 'class="feasible"' not in html.split('id="points-table"')[1]
    assert len(_point_ids(client.get(base, params={"feasible": "true"}).text)) == 9
    assert len(_point_ids(client.get(base, params={"task": "deskP"}).text)) == 7
    assert "no points match" in client.get(base, params={"task": "nowhere"}).text
    for bad in ({"feasible": "maybe"}, {"order": "sideways"}, {"after": "-1"}):
        assert client.get(base, params=bad).status_code == 422, bad
    assert client.get(base, params={"after": 5, "before": 9}).status_code == 422


@pytest.mark.parametrize("order", ["newest", "oldest"])
def test_points_table_pages_forward_and_back_in_either_order(
    stocked: dict[str, Any], order: str
) -> None:
    """Through the poll's table fragment (the page's own links, without its pictures)."""
    client = stocked["client"]
    base = f"/ui/api/kbs/default/types/{stocked['blocked']}"

    def table(query: str) -> str:
        return client.get(base + query).json()["fragments"]["points-panel"]

    html = table(f"?limit=10&order={order}")
    assert _link(html, "prev-page") is None
    pages = [_point_ids(html)]
    while (href := _link(html, "next-page")) is not None:
        html = table(href)
        pages.append(_point_ids(html))
    assert [len(p) for p in pages] == [10, 10, 7]
    flat = [i for page in pages for i in page]
    assert flat == sorted(flat, reverse=order == "newest") and len(set(flat)) == 27
    back = []
    while (href := _link(html, "prev-page")) is not None:
        html = table(href)
        back.append(_point_ids(html))
    assert back == [pages[1], pages[0]]
    assert _link(html, "first-page") is not None


def test_type_json_carries_the_filtered_table(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    url = f"/ui/api/kbs/default/types/{stocked['blocked']}"
    data = client.get(url, params={"feasible": "true", "order": "oldest"}).json()
    assert data["table"]["n_matching"] == 9
    assert all(p["feasible"] for p in data["table"]["points"])
    assert "feasible=true" in data["poll"]
    assert len(_point_ids(data["fragments"]["points-panel"])) == 9


def test_overview_pages_its_types(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    first = client.get("/", params={"kb": "default", "limit": 1}).text
    assert len(_rows(first, "types-rows")) == 1 and "types 1-1 of 2" in first
    second = client.get("/" + _link(first, "types-next").lstrip("/")).text
    assert len(_rows(second, "types-rows")) == 1 and "types 2-2 of 2" in second
    assert _link(second, "types-next") is None and _link(second, "types-prev")
    assert set(_rows(first, "types-rows")) != set(_rows(second, "types-rows"))


def test_overview_lists_bases_types_with_provenance_and_workers(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    page = client.get("/", params={"kb": "default"})
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
    assert 'data-poll="/ui/api/overview?kb=default&amp;offset=0&amp;limit=50"' in html
    assert "types 1-2 of 2" in html


def test_the_landing_page_opens_the_most_recently_active_base(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    # `lab` got its point last: it opens, not the `default` that holds more
    assert 'data-poll="/ui/api/overview?kb=lab&amp;' in client.get("/").text
    _post(client, "default", [make_point(99, graph=make_graph("Inv-kin", ("box1",)))])
    assert 'data-poll="/ui/api/overview?kb=default&amp;' in client.get("/").text
    assert client.get("/ui/api/overview").json()["kb"] == "default"


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
    before = client.get("/ui/api/overview", params={"kb": "default"}).json()
    assert before["kb"] == "default"
    assert {t["type_id"]: t["n_points"] for t in before["types"]}[stocked["blocked"]] == 27
    assert set(before["fragments"]) == {"kbs-rows", "types-rows", "types-panel", "workers-rows"}
    _post(
        client,
        "default",
        [
            make_point(100 + i, graph=make_graph("Inv-kin", ("box1",)), worker="late-worker")
            for i in range(3)
        ],
    )
    after = client.get("/ui/api/overview", params={"kb": "default"}).json()
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
    assert len(_point_ids(html)) == 10
    assert "27 of 27 points match" in html


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
    # The engine answers the uncertainty with P(feasible): each cell names its sd.
    assert all(" · sd " in r.find(f"{SVG_NS}title").text for r in cells)
    assert any(g.get("class") == "cp-legend-unsure" for g in root.iter(f"{SVG_NS}g"))
    assert client.get(url, params={"n": 1000}).status_code == 422


def test_type_json_follows_new_points(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    url = f"/ui/api/kbs/default/types/{stocked['shelf']}"
    before = client.get(url).json()
    assert before["n_points"] == 4
    assert set(before["fragments"]) == {
        "stats-panel",
        "provenance-panel",
        "surrogate-panel",
        "dims-panel",
        "relevance-panel",
        "tasks-panel",
        "points-panel",
    }
    _post(client, "default", [make_point(7, graph=make_graph("Plan-motion", ("shelf",)))])
    after = client.get(url).json()
    assert after["n_points"] == 5 and after["figure_key"] != before["figure_key"]
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


def test_overview_queries_do_not_grow_with_the_number_of_types(core_client: Any) -> None:
    from sqlalchemy import event

    store = core_client.app.state.store
    counted: list[str] = []

    def count(*args: Any) -> None:
        counted.append(args[2])

    def statements() -> int:
        counted.clear()
        event.listen(store.engine, "before_cursor_execute", count)
        try:
            assert core_client.get("/ui/api/overview").status_code == 200
        finally:
            event.remove(store.engine, "before_cursor_execute", count)
        return len(counted)

    def add_types(start: int, n: int) -> None:
        graphs = [make_graph("Inv-kin", (f"body{k}",)) for k in range(start, start + n)]
        _post(core_client, "default", [make_point(k, graph=g) for k, g in enumerate(graphs)])

    add_types(0, 2)
    few = statements()
    add_types(2, 20)
    assert statements() == few


def test_a_whole_knowledge_base_exports_as_one_zip(stocked: dict[str, Any]) -> None:
    import csv
    import io
    import json
    import zipfile

    client = stocked["client"]
    response = client.get("/ui/kbs/default/export.zip")
    assert response.status_code == 200
    assert response.headers["content-type"] == "application/zip"
    assert "attachment" in response.headers["content-disposition"]
    archive = zipfile.ZipFile(io.BytesIO(response.content))
    meta = json.loads(archive.read("types.json"))
    assert meta["kb"] == "default"
    by_id = {t["type_id"]: t for t in meta["types"]}
    assert set(by_id) == {stocked["blocked"], stocked["shelf"]}
    assert by_id[stocked["blocked"]]["graph"]["nodes"] and by_id[stocked["blocked"]]["space"]
    rows = list(
        csv.DictReader(io.StringIO(archive.read(f"points/{stocked['blocked']}.csv").decode()))
    )
    assert len(rows) == 27 and {r["task"] for r in rows} == {"desk", "deskP"}
    assert client.get("/ui/kbs/nope/export.zip").status_code == 404
    assert 'href="/ui/kbs/default/export.zip"' in client.get("/", params={"kb": "default"}).text


def test_choosing_heat_map_axes_keeps_the_table_filters(stocked: dict[str, Any]) -> None:
    client = stocked["client"]
    html = client.get(
        f"/ui/kbs/default/types/{stocked['blocked']}", params={"feasible": "false", "task": "desk"}
    ).text
    form = re.search(r'<form class="dims" method="get">(.*?)</form>', html, re.S).group(1)
    assert '<input type="hidden" name="feasible" value="false">' in form
    assert '<input type="hidden" name="task" value="desk">' in form

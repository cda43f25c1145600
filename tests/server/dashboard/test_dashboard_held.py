"""The point the type's pictures are drawn through: chosen by the user from the points table,
by default the newest feasible point, named on the page and in the pictures (issue 56.1); a
page per point (issue 56.5)."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.service_support import make_graph, make_point


@pytest.fixture
def stocked(core_client: Any) -> dict[str, Any]:
    graph = make_graph("Inv-kin", ("box1",))
    points = [make_point(i, graph=graph, task="desk", run=f"run-{i % 2}") for i in range(10)]
    results = core_client.post("/v1/kbs/default/points", json={"points": points}).json()["results"]
    ids = [r["point_id"] for r in results]
    feasible = [pid for pid, p in zip(ids, points, strict=True) if p["feasible"]]
    other = make_point(0, graph=make_graph("Plan-motion", ("shelf",)))
    elsewhere = core_client.post("/v1/kbs/default/points", json={"points": [other]}).json()
    return {
        "client": core_client,
        "type_id": results[0]["type_id"],
        "ids": ids,
        "newest_feasible": max(feasible),
        "other_point": elsewhere["results"][0]["point_id"],
    }


def _held_note(html: str) -> str:
    found = re.search(r'<p id="held-note" class="note" data-point-id="(\d*)">', html)
    assert found, "no held note"
    return found.group(1)


def test_the_pictures_go_through_the_newest_feasible_point_by_default(
    stocked: dict[str, Any],
) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    html = client.get(f"/ui/kbs/default/types/{type_id}").text
    newest = stocked["newest_feasible"]
    assert _held_note(html) == str(newest)
    assert f"point #{newest}, the newest feasible point" in html
    assert f'class="feasible held" data-point-id="{newest}"' in html
    svg = client.get(f"/ui/kbs/default/types/{type_id}/heatmap.svg").text
    assert f'class="cp-held" data-point-id="{newest}"' in svg


def test_a_point_chosen_in_the_table_is_held_everywhere(stocked: dict[str, Any]) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    chosen = stocked["ids"][1]  # an infeasible point (i % 3 != 0)
    html = client.get(f"/ui/kbs/default/types/{type_id}").text
    link = re.search(rf'href="(\?[^"]*hold={chosen})"', html)
    assert link, "no hold link for the point"
    page = client.get(f"/ui/kbs/default/types/{type_id}" + link.group(1).replace("&amp;", "&"))
    assert _held_note(page.text) == str(chosen) and f"point #{chosen}, as chosen" in page.text
    assert f'class="infeasible held" data-point-id="{chosen}"' in page.text
    assert 'id="hold-default"' in page.text
    for figure in ("heatmap.svg", "slices.svg"):
        assert f"hold={chosen}" in page.text.split(f"/{figure}?")[1].split('"')[0]
        svg = client.get(f"/ui/kbs/default/types/{type_id}/{figure}", params={"hold": chosen})
        assert f'class="cp-held" data-point-id="{chosen}"' in svg.text
    poll = client.get(f"/ui/api/kbs/default/types/{type_id}", params={"hold": chosen}).json()
    assert f"hold={chosen}" in poll["poll"]
    assert f'class="infeasible held" data-point-id="{chosen}"' in poll["fragments"]["points-panel"]


def test_holding_a_point_of_another_type_is_a_404(stocked: dict[str, Any]) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    page = client.get(f"/ui/kbs/default/types/{type_id}", params={"hold": stocked["other_point"]})
    assert page.status_code == 404 and "has no point" in page.text
    svg = client.get(
        f"/ui/kbs/default/types/{type_id}/heatmap.svg", params={"hold": stocked["other_point"]}
    )
    assert svg.status_code == 404


def test_each_point_has_a_page(stocked: dict[str, Any]) -> None:
    client, type_id = stocked["client"], stocked["type_id"]
    pid = stocked["ids"][3]
    page = client.get(f"/ui/kbs/default/points/{pid}")
    assert page.status_code == 200
    assert f"Point {pid}" in page.text and "run-1" in page.text and "desk" in page.text
    assert f"/ui/kbs/default/types/{type_id}?hold={pid}" in page.text
    assert "#pose" in page.text
    missing = client.get("/ui/kbs/default/points/999999")
    assert missing.status_code == 404 and "has no point #999999" in missing.text
    assert client.get("/ui/kbs/default/points/abc").status_code == 422

"""The history view (points and feasible share over time, per task or per type) and the slice
view (P(feasible) along each decision, most relevant first)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

from pydantic import TypeAdapter

from contract.models import Domain
from server.dashboard.heatmap import Slice
from server.dashboard.history_svg import render_history_svg
from server.dashboard.slices import render_slices_svg
from server.services import browse
from tests.service_support import make_graph, make_point

SVG_NS = "{http://www.w3.org/2000/svg}"
SPACE = TypeAdapter(dict[str, Domain]).validate_python(
    {
        "#dir": {"kind": "categorical", "choices": ["front", "top"]},
        "#pose": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 2.0]},
    }
)


def _post(client: Any, points: list[dict[str, Any]]) -> str:
    response = client.post("/v1/kbs/default/points", json={"points": points})
    assert response.status_code == 201, response.text
    return response.json()["results"][0]["type_id"]


def test_history_counts_points_and_feasible_ones_per_task_and_per_type(core_client: Any) -> None:
    store = core_client.app.state.store
    blocked = make_graph("Inv-kin", ("box1",))
    type_id = _post(
        core_client,
        [make_point(i, graph=blocked, task="desk" if i < 9 else "pack") for i in range(12)]
        + [make_point(12, graph=blocked)],
    )
    _post(
        core_client, [make_point(i, graph=make_graph("Plan-motion", ("shelf",))) for i in range(4)]
    )
    per_task = browse.history(store, "default", type_id, buckets=5)
    assert per_task.series == ["desk", "pack", browse.NO_TASK]
    assert per_task.totals == {"desk": 9, "pack": 3, browse.NO_TASK: 1}
    assert sum(b.n["desk"] for b in per_task.buckets) == 9
    # make_point: feasible when i % 3 == 0 (0, 3, 6 of desk; 9 of pack; 12)
    assert sum(b.n_feasible["desk"] for b in per_task.buckets) == 3
    per_type = browse.history(store, "default", buckets=5, max_series=1)
    assert per_type.series[-1] == "other" and sum(per_type.totals.values()) == 17
    svg = ET.fromstring(render_history_svg(per_task, "task"))
    groups = [g for g in svg.iter(f"{SVG_NS}g") if g.get("class") == "cp-history-series"]
    assert [g.get("data-series") for g in groups] == ["desk", "pack", browse.NO_TASK]
    empty = render_history_svg(browse.History([], [], {}), "task")
    assert "no points yet" in empty
    ET.fromstring(empty)


def _right_half_feasible(xs: list[dict[str, Any]]) -> list[float]:
    return [1.0 if x["#pose"][1] > 1.0 else 0.0 for x in xs]


def test_slices_put_the_most_relevant_dimension_first_with_its_curve() -> None:
    observed = [
        ({"#dir": "top", "#pose": [0.2, 1.5]}, True),
        ({"#dir": "front", "#pose": [0.7, 0.4]}, False),
        ({"#dir": "top", "#pose": [0.9, 0.1]}, False),
    ]
    held = Slice({"#pose": [0.9, 0.1]}, "point #3", {"#dir": "top"}, 3)
    svg = ET.fromstring(
        render_slices_svg(
            SPACE, _right_half_feasible, observed, held, {"#pose[0]": 3.0, "#pose[1]": 0.3}
        )
    )
    panels = [g for g in svg.iter(f"{SVG_NS}g") if g.get("class") == "cp-slice-panel"]
    assert [g.get("data-dim") for g in panels] == ["#pose[1]", "#pose[0]", "#dir"]
    bars = [r for r in svg.iter(f"{SVG_NS}rect") if r.get("class") == "cp-relevance"]
    assert [float(b.get("data-relevance")) for b in bars] == [1.0, 0.1]
    curve = panels[0].find(f"{SVG_NS}polyline").get("points").split()
    ys = [float(p.split(",")[1]) for p in curve]
    assert ys[0] > ys[-1]  # P rises from 0 to 1 along #pose[1]: y goes up the picture
    marks = [c for c in panels[0].iter(f"{SVG_NS}circle")]
    assert sorted(c.get("data-feasible") for c in marks) == ["0", "0", "1"]
    # faded by distance from the held point in #pose[0] and #dir: the held point itself is whole
    closeness = {
        c.get("data-feasible") + c.get("cx"): float(c.get("data-closeness")) for c in marks
    }
    assert max(closeness.values()) == 1.0 and min(closeness.values()) < 0.5
    held_line = [e for e in panels[0].iter() if e.get("class") == "cp-held"]
    assert len(held_line) == 1 and held_line[0].get("data-point-id") == "3"
    no_model = render_slices_svg(SPACE, None, observed, held, {})
    assert "no surrogate yet" in no_model and "<polyline" not in no_model


def test_history_and_slice_images_are_served(core_client: Any) -> None:
    core_client.app.state.predict = None  # the core alone: its engine is never started
    type_id = _post(core_client, [make_point(i, task="desk") for i in range(6)])
    for url in (
        f"/ui/kbs/default/types/{type_id}/history.svg",
        f"/ui/kbs/default/types/{type_id}/slices.svg",
        "/ui/kbs/default/history.svg",
    ):
        response = core_client.get(url)
        assert response.status_code == 200 and response.headers["content-type"] == "image/svg+xml"
        ET.fromstring(response.text)
    assert core_client.get("/ui/kbs/nope/history.svg").status_code == 404
    assert core_client.get("/ui/kbs/default/types/0123abcd/slices.svg").status_code == 404
    page = core_client.get(f"/ui/kbs/default/types/{type_id}").text
    assert 'id="slices"' in page and 'id="history"' in page
    assert 'id="history"' in core_client.get("/").text

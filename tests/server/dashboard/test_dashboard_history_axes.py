"""The history over time with idle pauses left out, by point or by run, with its values on
hover (issue 56.3)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from server.dashboard.history_svg import render_history_svg
from server.services import browse
from tests.service_support import make_graph, make_point

SVG_NS = "{http://www.w3.org/2000/svg}"
T0 = datetime(2026, 1, 1, tzinfo=UTC)


def _rows(seconds: list[float], runs: list[str]) -> list[browse.Row]:
    return [
        (k, T0 + timedelta(seconds=s), k % 2 == 0, run, "desk")
        for k, (s, run) in enumerate(zip(seconds, runs, strict=True))
    ]


def test_an_idle_pause_is_left_out_of_the_time_axis() -> None:
    # two bursts of ten points a second apart, three hours between them
    seconds = [float(k) for k in range(10)] + [3 * 3600.0 + k for k in range(10)]
    _, where, gaps = browse._by_active_time(_rows(seconds, ["a"] * 20), 10)
    assert len(gaps) == 1 and gaps[0][1] == pytest.approx(3 * 3600 - 9)
    # the bursts share the axis evenly instead of sitting in its two corners
    # (on a plain clock the first would all be in bucket 0 and the second in bucket 9)
    assert max(where[:10]) <= 5 <= min(where[10:]) and len(set(where)) == 10
    assert gaps[0][0] == where[10]  # the gap is drawn where the second burst starts


def test_by_point_and_by_run_buckets() -> None:
    rows = _rows([float(k) for k in range(12)], ["r1"] * 3 + ["r2"] * 6 + ["r3"] * 3)
    out, where = browse._by_point(rows, 4)
    assert [b.label for b in out] == ["points 1-3", "points 4-6", "points 7-9", "points 10-12"]
    assert where == [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3]
    out, where = browse._by_run(rows, 30)
    assert [b.label for b in out] == ["run r1", "run r2", "run r3"]
    assert where == [0] * 3 + [1] * 6 + [2] * 3
    out, where = browse._by_run(rows, 2)
    assert [b.label for b in out] == ["runs 1-2", "run r3"] and where[-1] == 1


@pytest.mark.parametrize("axis", ["time", "point", "run"])
def test_each_axis_is_served_with_values_on_hover(core_client: Any, axis: str) -> None:
    graph = make_graph("Inv-kin", ("box1",))
    points = [make_point(i, graph=graph, task="desk", run=f"run-{i // 4}") for i in range(12)]
    results = core_client.post("/v1/kbs/default/points", json={"points": points}).json()
    type_id = results["results"][0]["type_id"]
    for url in (f"/ui/kbs/default/types/{type_id}/history.svg", "/ui/kbs/default/history.svg"):
        svg = core_client.get(url, params={"axis": axis})
        assert svg.status_code == 200
        root = ET.fromstring(svg.text)
        marks = [g for g in root.iter(f"{SVG_NS}g") if g.get("class") == "cp-history-mark"]
        assert sum(int(g.get("data-n")) for g in marks) == 12
        tips = [g.find(f"{SVG_NS}title").text for g in marks]
        assert all("points" in tip and "feasible" in tip for tip in tips)
        if axis == "run":
            assert any("run run-0" in tip for tip in tips)
    assert core_client.get("/ui/kbs/default/history.svg", params={"axis": "day"}).status_code == 422


def test_the_narrow_history_fits_a_phone() -> None:
    rows = _rows([float(k) for k in range(12)], ["a"] * 12)
    out, _ = browse._by_point(rows, 6)
    for b, k in zip(out, range(6), strict=True):
        b.n["desk"] = 2
        b.n_feasible["desk"] = k % 3
    history = browse.History(out, ["desk"], {"desk": 12}, "point")
    wide = ET.fromstring(render_history_svg(history, "task"))
    narrow = ET.fromstring(render_history_svg(history, "task", narrow=True))
    assert float(narrow.get("width")) < 360 < float(wide.get("width"))


def test_the_history_images_take_the_columns_the_page_asks_for(core_client: Any) -> None:
    points = [make_point(i, graph=make_graph("Inv-kin", ("box1",))) for i in range(6)]
    results = core_client.post("/v1/kbs/default/points", json={"points": points}).json()
    type_id = results["results"][0]["type_id"]
    for url in (f"/ui/kbs/default/types/{type_id}/history.svg", "/ui/kbs/default/history.svg"):
        narrow = core_client.get(url, params={"axis": "time", "cols": 1})
        wide = core_client.get(url, params={"axis": "time", "cols": 2})
        assert narrow.status_code == wide.status_code == 200
        width = [float(ET.fromstring(r.text).get("width")) for r in (narrow, wide)]
        assert width[0] < 360 < width[1]

"""The dashboard in a real headless Chromium, against a real `cpkb serve` holding real points
(Chromium from conftest.py)."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest

from client import CpkbClient
from cpkb.embedded import embedded_service
from tests.server.dashboard.browser_support import (
    LIVE_TIMEOUT_MS,
    clipped,
    launch,
    no_sideways_scroll,
)
from tests.service_support import make_graph, make_point
from tests.wait_support import wait_until

pytestmark = pytest.mark.browser


def _boundary_points(graph: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Points over the unit cube, infeasible exactly where #pose[2] > 0.5, one #dir only."""
    rng = random.Random(5)
    points = []
    for i in range(n):
        pose = [rng.random() for _ in range(3)]
        point = make_point(i, graph=graph, feasible=pose[2] <= 0.5, task="boundary")
        point["x"] = {"#dir": "top", "#pose": pose}
        points.append(point)
    return points


def test_heat_map_shows_a_boundary_off_the_first_two_dimensions_by_default(
    chromium: str, sqlite_url: str
) -> None:
    from playwright.sync_api import expect, sync_playwright

    cube = {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]}
    graph = make_graph("Inv-kin", ("box1",), pose_domain=cube)
    with embedded_service(sqlite_url) as url, CpkbClient(url) as client:
        type_id = client.post_points("default", _boundary_points(graph, 60))[0].type_id

        def fitted() -> bool:
            state = client.get_type("default", type_id).surrogate
            return state is not None and bool(state.lengthscales) and state.n_fitted == 60

        wait_until(fitted, what="the type's first fit")
        with sync_playwright() as playwright:
            browser = launch(playwright, chromium)
            try:
                page = browser.new_page(viewport={"width": 1200, "height": 900})
                page.goto(f"{url}/ui/kbs/default/types/{type_id}")
                axes = {
                    page.locator('select[name="x"]').input_value(),
                    page.locator('select[name="y"]').input_value(),
                }
                assert "#pose[2]" in axes
                probs = page.eval_on_selector_all(
                    "#heatmap rect.cp-cell[data-p]", "cells => cells.map(c => +c.dataset.p)"
                )
                assert len(probs) >= 100
                assert max(probs) > 0.7 and min(probs) < 0.3
                expect_text = page.locator("#heatmap .cp-slice").text_content() or ""
                assert "the newest feasible point" in expect_text

                # The map goes through the held point: the cell it lies in says about what the
                # model says at the point itself (issue 56.1: 0.04 on the map, 0.81 at it).
                cell_p = page.evaluate(
                    """() => {
                    const ring = document.querySelector("#heatmap circle.cp-held");
                    const cx = +ring.getAttribute("cx"), cy = +ring.getAttribute("cy");
                    for (const r of ring.closest("g").querySelectorAll("rect.cp-cell")) {
                      const x = +r.getAttribute("x"), y = +r.getAttribute("y");
                      if (cx >= x && cx < x + +r.getAttribute("width") &&
                          cy >= y && cy < y + +r.getAttribute("height")) return +r.dataset.p;
                    }
                    return null;
                }"""
                )
                held_id = int(page.locator("#held-note").get_attribute("data-point-id") or -1)
                held_x = next(
                    p.x for p in client.iter_points("default", type_id) if p.point_id == held_id
                )
                at_point = client.predict("default", type_id, [held_x])[0]
                assert cell_p is not None and abs(cell_p - at_point) < 0.35, (cell_p, at_point)

                # Uncertainty shows: the choices no point holds are hatched all over, the one
                # the points hold is not, and the legend says what the hatch means.
                unsure = page.eval_on_selector_all(
                    "#heatmap g.cp-heatmap-panel",
                    """panels => Object.fromEntries(panels.map(g => [g.dataset.panel, [
                        g.querySelectorAll("rect.cp-cell[data-unsure]").length,
                        g.querySelectorAll("rect.cp-cell").length,
                        g.querySelectorAll("rect.cp-unsure").length]]))""",
                )
                held = unsure.pop("#dir=top")
                assert held[0] < held[1]
                assert unsure and all(u == n and h > 0 for u, n, h in unsure.values())
                expect(page.locator("#heatmap .cp-legend-unsure")).to_be_visible()
                expect(page.locator("#heatmap .cp-legend-unsure")).to_contain_text("unsure")
                assert clipped(page) == []
            finally:
                browser.close()


def test_pages_fit_a_400_px_wide_screen(chromium: str, sqlite_url: str) -> None:
    from playwright.sync_api import expect, sync_playwright

    with embedded_service(sqlite_url) as url, CpkbClient(url) as client:
        type_id = client.post_points("default", _points(make_graph(), 0, 12))[0].type_id
        with sync_playwright() as playwright:
            browser = launch(playwright, chromium)
            try:
                page = browser.new_page(viewport={"width": 400, "height": 800})
                page.goto(f"{url}/")
                expect(page.locator("#types-table tbody tr")).to_have_count(1)
                assert no_sideways_scroll(page)
                page.goto(f"{url}/ui/kbs/default/types/{type_id}")
                expect(page.locator("svg.cp-graph")).to_be_visible()
                assert no_sideways_scroll(page)
            finally:
                browser.close()


def _points(graph: dict[str, Any], start: int, n: int) -> list[dict[str, Any]]:
    return [
        make_point(i, graph=graph, task="desk", run="run-1", rollout=i, worker="browser-worker")
        for i in range(start, start + n)
    ]


def test_dashboard_in_headless_chromium(chromium: str, sqlite_url: str, tmp_path: Path) -> None:
    from playwright.sync_api import expect, sync_playwright

    blocked = make_graph("Inv-kin", ("box1",))
    shelf = make_graph("Plan-motion", ("shelf",))
    with embedded_service(sqlite_url) as url, CpkbClient(url) as client:
        type_id = client.post_points("default", _points(blocked, 0, 40))[0].type_id
        client.post_points("default", _points(shelf, 0, 6))
        errors: list[str] = []
        with sync_playwright() as playwright:
            browser = launch(playwright, chromium)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                page.on("pageerror", lambda exc: errors.append(str(exc)))
                page.on(
                    "console",
                    lambda msg: errors.append(msg.text) if msg.type == "error" else None,
                )
                page.on(
                    "response",
                    lambda r: errors.append(f"{r.status} {r.url}") if r.status >= 400 else None,
                )
                page.goto(f"{url}/")
                types = page.locator("#types-table tbody tr")
                expect(types).to_have_count(2)
                row = page.locator(f'#types-table tr[data-type-id="{type_id}"]')
                expect(row.locator(".n-points")).to_have_text("40")
                expect(row).to_contain_text("Inv-kin")
                expect(page.locator("#workers-table")).to_contain_text("browser-worker")

                # Points arriving while the page is open show up without a reload.
                client.post_points("default", _points(blocked, 40, 5))
                expect(row.locator(".n-points")).to_have_text("45", timeout=LIVE_TIMEOUT_MS)
                expect(page.locator("#live")).to_contain_text("live")
                page.screenshot(path=tmp_path / "overview.png", full_page=True)

                row.locator("a.type-link").click()
                page.wait_for_url(f"**/ui/kbs/default/types/{type_id}")
                expect(page.locator("svg.cp-graph g.cp-node")).to_have_count(4)
                expect(page.locator('svg.cp-graph g[data-role="failure"]')).to_contain_text(
                    "Inv-kin"
                )
                panels = page.locator("#heatmap svg.cp-heatmap g.cp-heatmap-panel")
                expect(panels).to_have_count(5)
                expect(page.locator("#heatmap .cp-observed")).to_have_count(45)
                expect(page.locator("#points-table tbody tr")).to_have_count(45)
                expect(page.locator("#surrogate-panel")).to_be_visible()

                client.post_points("default", _points(blocked, 45, 3))
                expect(page.locator("#n-points")).to_have_text("48", timeout=LIVE_TIMEOUT_MS)
                expect(page.locator("#heatmap .cp-observed")).to_have_count(
                    48, timeout=LIVE_TIMEOUT_MS
                )
                shot = tmp_path / "type.png"
                page.screenshot(path=shot, full_page=True)
            finally:
                browser.close()
    assert errors == []
    for name in ("overview.png", "type.png"):
        data = (tmp_path / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000

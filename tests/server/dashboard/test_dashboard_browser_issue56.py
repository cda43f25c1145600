"""What issue 56 asked of the dashboard, in headless Chromium against one real `cpkb serve`:
the held point chosen from the table (1), relevance that follows each fit without a reload (2),
the most recent base first and the history's axes (3), a phone that stacks the figures, dark
markers that show, /login styled and HTML errors (4), sortable columns, parallel coordinates,
a page per point and the compare view (5)."""

from __future__ import annotations

import random
import re
from collections.abc import Iterator
from typing import Any

import pytest

from client import CpkbClient
from cpkb.embedded import embedded_service
from tests.server.dashboard.browser_support import LIVE_TIMEOUT_MS, launch, no_sideways_scroll
from tests.service_support import make_graph, make_point
from tests.wait_support import wait_until

pytestmark = [pytest.mark.browser, pytest.mark.slow]
CUBE = {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]}


def _cube_points(graph: dict[str, Any], start: int, n: int) -> list[dict[str, Any]]:
    """Infeasible exactly where #pose[2] > 0.5, from two tasks and four runs."""
    rng = random.Random(start)
    points = []
    for i in range(start, start + n):
        pose = [rng.random() for _ in range(3)]
        point = make_point(
            i,
            graph=graph,
            feasible=pose[2] <= 0.5,
            task="desk" if i % 4 else "pack",
            run=f"run-{i % 4}",
        )
        point["x"] = {"#dir": "top", "#pose": pose}
        points.append(point)
    return points


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    db = tmp_path_factory.mktemp("issue56") / "kb.sqlite"
    graph = make_graph("Inv-kin", ("box1",), pose_domain=CUBE)
    with embedded_service(f"sqlite:///{db}") as url, CpkbClient(url) as client:
        type_id = client.post_points("default", _cube_points(graph, 0, 40))[0].type_id
        client.create_kb("lab")
        client.post_points("lab", _cube_points(graph, 100, 5))
        yield {"url": url, "client": client, "graph": graph, "type": type_id}


@pytest.fixture(scope="module")
def browser(chromium: str) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = launch(playwright, chromium)
        try:
            yield browser
        finally:
            browser.close()


def _type_url(service: dict[str, Any], kb: str = "default") -> str:
    return f"{service['url']}/ui/kbs/{kb}/types/{service['type']}"


def test_the_user_holds_a_point_from_the_table(browser: Any, service: dict[str, Any]) -> None:
    from playwright.sync_api import expect

    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.goto(_type_url(service))
    note = page.locator("#held-note")
    newest = note.get_attribute("data-point-id")
    expect(note).to_contain_text("the newest feasible point")
    expect(page.locator(f'#points-table tr.held[data-point-id="{newest}"]')).to_have_count(1)
    expect(page.locator(f'#heatmap circle.cp-held[data-point-id="{newest}"]')).to_have_count(1)

    row = page.locator("#points-table tr.infeasible").first
    chosen = row.get_attribute("data-point-id")
    row.locator("a.hold-link").click()
    page.wait_for_url(re.compile(rf"hold={chosen}"))
    expect(note).to_contain_text(f"point #{chosen}, as chosen")
    expect(page.locator(f'#heatmap circle.cp-held[data-point-id="{chosen}"]')).to_have_count(1)
    expect(page.locator(f'#slices line.cp-held[data-point-id="{chosen}"]')).to_have_count(3)
    faded = page.eval_on_selector_all(
        "#heatmap .cp-observed", "marks => marks.map(m => +m.getAttribute('opacity'))"
    )
    assert min(faded) < 0.5 < max(faded)  # points off the slice fade, points on it do not
    page.locator("#hold-default").click()
    expect(note).to_contain_text("the newest feasible point")
    page.close()


def test_relevance_follows_each_fit_without_a_reload(browser: Any, service: dict[str, Any]) -> None:
    from playwright.sync_api import expect

    client, type_id = service["client"], service["type"]
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.goto(_type_url(service))
    expect(page.locator("#relevance .chip[data-column]").first).to_be_visible(
        timeout=LIVE_TIMEOUT_MS
    )
    before = wait_until(
        lambda: (
            (client.get_type("default", type_id).surrogate or None)
            and client.get_type("default", type_id).surrogate.version
        ),
        what="a first fit",
    )
    names = page.eval_on_selector_all("#relevance .chip", "c => c.map(e => e.dataset.column)")
    assert "#dir=top" in names and "#pose[2]" in names
    client.post_points("default", _cube_points(service["graph"], 40, 30))
    after = wait_until(
        lambda: (v := client.get_type("default", type_id).surrogate.version) != before and v,
        timeout=300,
        what="a refit after 30 more points",
    )
    expect(page.locator("#relevance")).to_contain_text(f"fit v{after}", timeout=LIVE_TIMEOUT_MS)
    page.close()


def test_landing_page_and_history_axes(browser: Any, service: dict[str, Any]) -> None:
    from playwright.sync_api import expect

    client = service["client"]
    client.post_points("lab", _cube_points(service["graph"], 200, 2))
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.goto(f"{service['url']}/")
    expect(page.locator("#kbs-table tr.chosen")).to_contain_text("lab")
    page.goto(_type_url(service))
    history = page.locator("#history")
    page.locator('.axis-choice button[data-axis="run"]').click()
    expect(page.locator('.axis-choice button[data-axis="run"]')).to_have_attribute(
        "aria-pressed", "true"
    )
    expect(history.locator("g.cp-history-mark title").first).to_contain_text("run run-")
    page.locator('.axis-choice button[data-axis="point"]').click()
    expect(history.locator("g.cp-history-mark title").first).to_contain_text("points 1-")
    page.close()


def _min_font_px(page: Any, selector: str) -> float:
    """The smallest rendered font size of the SVG text in `selector`, in CSS px."""
    return page.evaluate(
        """(selector) => {
        let least = Infinity;
        for (const svg of document.querySelectorAll(selector + " svg")) {
          const view = svg.viewBox.baseVal;
          const scale = svg.getBoundingClientRect().width / (view && view.width || 1);
          for (const t of svg.querySelectorAll("text")) {
            const size = parseFloat(getComputedStyle(t).fontSize) * scale;
            if (t.getBoundingClientRect().width > 0) least = Math.min(least, size);
          }
        }
        return least;
    }""",
        selector,
    )


def test_a_phone_stacks_the_figures_at_a_readable_size(
    browser: Any, service: dict[str, Any]
) -> None:
    from playwright.sync_api import expect

    page = browser.new_page(viewport={"width": 390, "height": 844}, device_scale_factor=1)
    page.goto(_type_url(service))
    expect(page.locator("#heatmap")).to_have_attribute("data-src", re.compile("cols=1"))
    expect(page.locator("#history")).to_have_attribute("data-src", re.compile("cols=1"))
    for figure in ("#heatmap", "#slices", "#history"):
        page.wait_for_function(
            f"+document.querySelector('{figure} svg').getAttribute('width') < 400",
            timeout=LIVE_TIMEOUT_MS,
        )
    lefts = page.eval_on_selector_all(
        "#heatmap g.cp-heatmap-panel rect.cp-cell:first-of-type",
        "cells => cells.map(c => Math.round(c.getBoundingClientRect().left))",
    )
    assert len(set(lefts)) == 1  # every panel in one column
    for figure in ("#heatmap", "#slices", "#history", "#parallel"):
        assert _min_font_px(page, figure) >= 8.5, figure
    assert no_sideways_scroll(page)
    page.close()


def _luminance(css: str) -> float:
    r, g, b = (int(c) / 255 for c in re.findall(r"\d+", css)[:3])

    def lin(c: float) -> float:
        return c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4

    return 0.2126 * lin(r) + 0.7152 * lin(g) + 0.0722 * lin(b)


def _contrast(a: str, b: str) -> float:
    la, lb = sorted((_luminance(a), _luminance(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)


def test_dark_mode_markers_login_and_html_errors(browser: Any, service: dict[str, Any]) -> None:
    from playwright.sync_api import expect

    page = browser.new_page(color_scheme="dark", viewport={"width": 1400, "height": 900})
    response = page.goto(_type_url(service))
    assert response.headers.get("content-encoding") == "gzip"
    panel = page.evaluate("getComputedStyle(document.querySelector('#slices')).backgroundColor")
    marks = page.eval_on_selector_all(
        '#slices circle.cp-slice-point[data-feasible="0"]',
        "ms => ms.map(m => getComputedStyle(m).fill)",
    )
    assert marks and min(_contrast(fill, panel) for fill in marks) >= 3.0
    lines = page.eval_on_selector_all(
        '#parallel polyline[data-feasible="0"]', "ls => ls.map(l => getComputedStyle(l).stroke)"
    )
    assert lines and min(_contrast(stroke, panel) for stroke in lines) >= 3.0

    login = page.goto(f"{service['url']}/login")
    assert login.status == 200
    box = page.evaluate("getComputedStyle(document.querySelector('main')).borderRadius")
    assert box == "8px"
    assert _luminance(page.evaluate("getComputedStyle(document.body).backgroundColor")) < 0.05

    bad = page.goto(_type_url(service) + "?feasible=maybe")
    assert bad.status == 422 and bad.headers["content-type"].startswith("text/html")
    expect(page.locator("h1")).to_have_text("Bad request")
    unknown = page.goto(_type_url(service) + "?colour=red")
    assert unknown.status == 422
    expect(page.locator(".error")).to_contain_text("colour")
    page.close()


def test_sortable_table_parallel_coordinates_point_pages_and_compare(
    browser: Any, service: dict[str, Any]
) -> None:
    from playwright.sync_api import expect

    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.goto(_type_url(service) + "?order=oldest&run=run-1")
    expect(page.locator("#points-count")).to_contain_text("points match")
    headings = page.eval_on_selector_all("#points-table thead th", "t => t.map(h => h.textContent)")
    column = headings.index("run")
    runs = page.eval_on_selector_all(
        "#points-table tbody tr", f"rows => rows.map(r => r.children[{column}].textContent)"
    )
    assert runs and set(runs) == {"run-1"}
    header = page.locator("#points-table thead th").first

    def ids() -> list[int]:
        return page.eval_on_selector_all(
            "#points-table tbody tr", "rows => rows.map(r => +r.dataset.pointId)"
        )

    header.click()
    assert ids() == sorted(ids())
    header.click()
    assert ids() == sorted(ids(), reverse=True)
    expect(header).to_have_attribute("aria-sort", "descending")
    lines = page.locator("#parallel polyline.cp-parallel-line")
    assert lines.count() >= 40

    first = page.locator("#points-table tbody tr a").first
    point_id = first.text_content()
    first.click()
    page.wait_for_url(re.compile(rf"/points/{point_id}$"))
    expect(page.locator("h1")).to_contain_text(f"Point {point_id}")
    expect(page.locator("#point-source")).to_contain_text("run-1")
    page.locator("#hold-here").click()
    expect(page.locator("#held-note")).to_contain_text(f"point #{point_id}")

    page.goto(f"{service['url']}/?kb=default")
    page.locator("#compare-form button").click()
    page.wait_for_url(re.compile(r"/ui/compare\?a=default&b=lab"))
    expect(page.locator(f'#compare-table tr[data-type-id="{service["type"]}"]')).to_be_visible()
    page.close()

"""The dashboard's tables, graph and themes in headless Chromium against one real `cpkb serve`:
filters and pages work and follow new points, no panel is clipped, the causal graph's labels do
not overlap, dark mode, a hidden tab does not poll, and the API docs render offline."""

from __future__ import annotations

from collections.abc import Iterator
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

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def _wide_graph() -> dict[str, Any]:
    """Decisions feeding connections and the failure directly: edges that skip a layer."""
    nodes: list[dict[str, Any]] = [{"id": "f", "role": "failure", "label": "Plan-motion"}]
    edges = []
    for i in range(3):
        nodes.append(
            {
                "id": f"d{i}",
                "role": "decision",
                "label": f"#pose{i}",
                "domain": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
            }
        )
        nodes.append({"id": f"c{i}", "role": "connection", "label": f"Sample-place-{i}"})
        edges.append({"source": f"d{i}", "target": f"c{i}", "label": "placement"})
        edges.append({"source": f"c{i}", "target": "f", "label": "moves through"})
        edges.append({"source": f"d{i}", "target": "f", "label": "pose"})
    nodes.append({"id": "o", "role": "context", "label": "shelf"})
    edges.append({"source": "o", "target": "f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    db = tmp_path_factory.mktemp("browser-views") / "kb.sqlite"
    graph = make_graph("Inv-kin", ("box1",))
    points = [
        make_point(i, graph=graph, task="desk" if i < 30 else "pack", run="r", worker="w")
        for i in range(40)
    ]
    wide = _wide_graph()
    wide_points = [
        {
            "graph": wide,
            "x": {f"#pose{k}": [0.1 * (i % 9), 0.5] for k in range(3)},
            "feasible": i % 2 == 0,
            "source": {"task": "wide"},
        }
        for i in range(6)
    ]
    with embedded_service(f"sqlite:///{db}") as url, CpkbClient(url) as client:
        type_id = client.post_points("default", points)[0].type_id
        wide_id = client.post_points("default", wide_points)[0].type_id
        yield {"url": url, "client": client, "graph": graph, "type": type_id, "wide": wide_id}


@pytest.fixture(scope="module")
def browser(chromium: str) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = launch(playwright, chromium)
        try:
            yield browser
        finally:
            browser.close()


def test_points_filters_pages_and_live_rows(browser: Any, service: dict[str, Any]) -> None:
    from playwright.sync_api import expect

    page = browser.new_page(viewport={"width": 1200, "height": 900})
    page.goto(f"{service['url']}/ui/kbs/default/types/{service['type']}")
    rows = page.locator("#points-table tbody tr")
    expect(rows).to_have_count(40)
    page.select_option('#points-filter select[name="feasible"]', "false")
    page.fill('#points-filter input[name="task"]', "desk")
    page.fill('#points-filter input[name="limit"]', "8")
    page.click('#points-filter button[type="submit"]')
    # desk is i < 30, feasible is i % 3 == 0: 20 infeasible desk points, 8 a page
    expect(page.locator("#points-count")).to_contain_text("20 of 40 points match")
    expect(rows).to_have_count(8)
    labels = page.eval_on_selector_all(
        "#points-table tbody tr td:nth-child(2)", "cells => cells.map(c => c.textContent)"
    )
    assert set(labels) == {"infeasible"}
    first_ids = page.eval_on_selector_all(
        "#points-table tbody tr", "rows => rows.map(r => +r.dataset.pointId)"
    )
    page.click("#next-page")
    expect(page.locator("#prev-page")).to_be_visible()
    page.click("#next-page")
    expect(rows).to_have_count(4)
    page.click("#prev-page")
    page.click("#prev-page")
    expect(page.locator("#prev-page")).to_have_count(0)
    back_ids = page.eval_on_selector_all(
        "#points-table tbody tr", "rows => rows.map(r => +r.dataset.pointId)"
    )
    assert back_ids == first_ids

    # A new matching point appears at the top of the first page without a reload.
    new = make_point(100, graph=service["graph"], feasible=False, task="desk")
    stored = service["client"].post_points("default", [new])[0].point_id
    expect(page.locator(f'#points-table tr[data-point-id="{stored}"]')).to_have_count(
        1, timeout=LIVE_TIMEOUT_MS
    )
    expect(page.locator("#points-count")).to_contain_text("21 of 41")
    page.close()


@pytest.mark.parametrize("width", [1200, 400])
def test_no_panel_is_clipped(browser: Any, service: dict[str, Any], width: int) -> None:
    page = browser.new_page(viewport={"width": width, "height": 900})
    for path in (
        "/",
        f"/ui/kbs/default/types/{service['type']}",
        f"/ui/kbs/default/types/{service['wide']}",
    ):
        page.goto(service["url"] + path)
        page.wait_for_load_state("load")
        assert clipped(page) == [], path
        assert no_sideways_scroll(page), path
    page.close()


def test_causal_graph_labels_do_not_overlap(browser: Any, service: dict[str, Any]) -> None:
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    page.goto(f"{service['url']}/ui/kbs/default/types/{service['wide']}")
    assert page.get_attribute("svg.cp-graph", "data-layout") == "dot"
    boxes = page.eval_on_selector_all(
        "svg.cp-graph text",
        "ts => ts.map(t => { const r = t.getBoundingClientRect();"
        " return [t.textContent, r.left, r.top, r.right, r.bottom]; })",
    )
    rects = page.eval_on_selector_all(
        "svg.cp-graph g.cp-node rect",
        "rs => rs.map(r => { const b = r.getBoundingClientRect();"
        " return [r.parentElement.dataset.id, b.left, b.top, b.right, b.bottom]; })",
    )
    page.close()

    def overlap(a: list[Any], b: list[Any]) -> bool:
        return a[1] < b[3] and b[1] < a[3] and a[2] < b[4] and b[2] < a[4]

    assert len(boxes) >= 7 + 10  # vertex names and notes, edge labels
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not overlap(a, b), (a[0], b[0])
    edge_labels = {"placement", "moves through", "pose", "collides"}
    for label in (b for b in boxes if b[0] in edge_labels):
        for rect in rects:
            assert not overlap(label, rect), (label[0], rect[0])


def test_dark_mode_follows_the_system(browser: Any, service: dict[str, Any]) -> None:
    page = browser.new_page(color_scheme="dark")
    page.goto(f"{service['url']}/ui/kbs/default/types/{service['type']}")
    background = page.evaluate("getComputedStyle(document.body).backgroundColor")
    text = page.evaluate("getComputedStyle(document.querySelector('svg.cp-graph text')).fill")
    page.close()
    channels = [int(c) for c in background[background.index("(") + 1 : -1].split(",")[:3]]
    assert max(channels) < 60, background
    assert min(int(c) for c in text[text.index("(") + 1 : -1].split(",")[:3]) > 150, text


def test_a_hidden_tab_does_not_poll(browser: Any, service: dict[str, Any]) -> None:
    page = browser.new_page()
    page.add_init_script(
        """(() => {
        let state = "hidden";
        Object.defineProperty(document, "visibilityState", { get: () => state });
        window.__show = () => {
          state = "visible";
          document.dispatchEvent(new Event("visibilitychange"));
        };
    })()"""
    )
    polls: list[str] = []
    page.on("request", lambda r: polls.append(r.url) if "/ui/api/" in r.url else None)
    page.goto(f"{service['url']}/")
    page.wait_for_timeout(7_000)  # longer than a poll period (5 s)
    assert polls == []
    with page.expect_request(lambda r: "/ui/api/overview" in r.url, timeout=LIVE_TIMEOUT_MS):
        page.evaluate("window.__show()")
    page.close()


def test_docs_and_redoc_render_with_every_outside_request_refused(
    browser: Any, service: dict[str, Any]
) -> None:
    from playwright.sync_api import expect

    url = service["url"]
    page = browser.new_page()
    outside: list[str] = []

    def offline(route: Any) -> None:
        if route.request.url.startswith(url):
            route.continue_()
        else:
            outside.append(route.request.resource_type)
            route.abort()

    page.route("**/*", offline)
    page.goto(f"{url}/docs")
    expect(page.locator(".swagger-ui .info .title")).to_contain_text("cpkb")
    expect(page.locator(".opblock").first).to_be_visible()
    page.goto(f"{url}/redoc")
    expect(page.locator("redoc h1, [role=main] h1").first).to_contain_text("cpkb")
    page.close()
    # Redoc's bundle links its own "API docs by Redocly" logo from its site: the one picture
    # missing offline. No script, style or font is asked from outside.
    assert set(outside) <= {"image"}, outside

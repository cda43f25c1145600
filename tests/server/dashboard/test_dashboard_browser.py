"""The dashboard in a real headless Chromium, against a real `cpkb serve` holding real points.

Needs Debian's `chromium` (`.ci/run` installs it); skipped, saying so, only where it is absent.
Playwright drives it through `executable_path`: no browser download.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

from client import CpkbClient
from cpkb.embedded import embedded_service
from tests.service_support import make_graph, make_point

pytestmark = pytest.mark.browser

CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
LIVE_TIMEOUT_MS = 60_000  # the page polls every 3 s; a loaded machine renders slowly


@pytest.fixture(scope="module")
def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None and Path("/usr/bin/chromium").exists():
        path = "/usr/bin/chromium"
    if path is None:
        pytest.skip("Chromium not found: install Debian's `chromium` package (.ci/run does)")
    return path


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
            browser = playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000})
                page.on("pageerror", lambda exc: errors.append(str(exc)))
                page.on(
                    "console",
                    lambda msg: errors.append(msg.text) if msg.type == "error" else None,
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
                expect(page.locator("#heatmap circle.cp-observed")).to_have_count(45)
                expect(page.locator("#points-table tbody tr")).to_have_count(45)
                expect(page.locator("#surrogate-panel")).to_be_visible()

                client.post_points("default", _points(blocked, 45, 3))
                expect(page.locator("#n-points")).to_have_text("48", timeout=LIVE_TIMEOUT_MS)
                expect(page.locator("#heatmap circle.cp-observed")).to_have_count(
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

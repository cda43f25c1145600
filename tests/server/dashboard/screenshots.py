"""The dashboard screenshots in docs/images: the type page at 1400x900 and 390x844, light and
dark, of a knowledge base filled with a known boundary (infeasible where #pose[2] > 0.5) once
its fit has landed. Run from the repository root:

    python -m tests.server.dashboard.screenshots docs/images

Each shot is the first screen of the page (what a visitor sees), quantised to 256 colours so
that the files stay small."""

from __future__ import annotations

import io
import shutil
import sys
import tempfile
from pathlib import Path

from PIL import Image

from client import CpkbClient
from cpkb.embedded import embedded_service
from tests.server.dashboard.browser_support import launch
from tests.server.dashboard.test_dashboard_browser_issue56 import CUBE, _cube_points
from tests.service_support import make_graph
from tests.wait_support import wait_until

SIZES = {"desktop": (1400, 900), "phone": (390, 844)}
THEMES = ("light", "dark")


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    graph = make_graph("Inv-kin", ("box1",), pose_domain=CUBE)
    with (
        tempfile.TemporaryDirectory() as tmp,
        embedded_service(f"sqlite:///{Path(tmp) / 'kb.sqlite'}") as url,
        CpkbClient(url) as client,
    ):
        type_id = client.post_points("default", _cube_points(graph, 0, 80))[0].type_id

        def fitted() -> bool:
            state = client.get_type("default", type_id).surrogate
            return state is not None and state.n_fitted == 80

        wait_until(fitted, timeout=600, what="the fit of all 80 points")
        shoot(f"{url}/ui/kbs/default/types/{type_id}", out)


def shoot(page_url: str, out: Path) -> None:
    """A screen from the feasibility section down, at each size in each theme."""
    from playwright.sync_api import sync_playwright

    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    with sync_playwright() as playwright:
        browser = launch(playwright, chromium)
        for size, (width, height) in SIZES.items():
            for theme in THEMES:
                page = browser.new_page(
                    viewport={"width": width, "height": height}, color_scheme=theme
                )
                page.goto(page_url)
                page.wait_for_timeout(3000)  # the figures fit themselves to the width
                page.evaluate(
                    "document.querySelector('#dims-panel').scrollIntoView({block: 'start'});"
                    "window.scrollBy(0, -50)"
                )
                shot = Image.open(io.BytesIO(page.screenshot()))
                small = shot.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT)
                small.save(out / f"type-page-{size}-{theme}.png", optimize=True)
                page.close()
        browser.close()


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images"))

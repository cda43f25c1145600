"""Launching Debian's Chromium through Playwright, and checks shared by the browser tests."""

from __future__ import annotations

from typing import Any

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
LIVE_TIMEOUT_MS = 60_000  # the pages poll every few seconds; a loaded machine renders slowly


def launch(playwright: Any, chromium: str) -> Any:
    return playwright.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)


def no_sideways_scroll(page: Any) -> bool:
    return page.evaluate(
        "document.scrollingElement.scrollWidth <= document.scrollingElement.clientWidth"
    )


def clipped(page: Any) -> list[str]:
    """Panels whose content is wider than they are, and SVG texts outside their picture."""
    return page.evaluate(
        """() => {
        const out = [];
        for (const el of document.querySelectorAll("section, .figure, main")) {
          if (el.scrollWidth > el.clientWidth + 1 && !el.classList.contains("scroll")
              && getComputedStyle(el).overflowX !== "auto")
            out.push("overflow " + (el.id || el.className || el.tagName));
        }
        for (const svg of document.querySelectorAll(".figure svg")) {
          const box = svg.getBoundingClientRect();
          for (const t of svg.querySelectorAll("text")) {
            const r = t.getBoundingClientRect();
            if (r.width === 0) continue;
            if (r.left < box.left - 1 || r.right > box.right + 1 ||
                r.top < box.top - 1 || r.bottom > box.bottom + 1)
              out.push("text outside " + svg.getAttribute("class") + ": " + t.textContent);
          }
          const parent = svg.parentElement.getBoundingClientRect();
          if (box.right > parent.right + 1)
            out.push("wider than its panel: " + svg.className.baseVal);
        }
        return out;
    }"""
    )

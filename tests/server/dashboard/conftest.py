"""The `chromium` fixture of the dashboard's browser tests (marker `browser`): the path of
Debian's `chromium` (`.ci/run` installs it); a test asking for it is skipped, saying so, only
where it is absent. Playwright drives it through `executable_path`: no browser download."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None and Path("/usr/bin/chromium").exists():
        path = "/usr/bin/chromium"
    if path is None:
        pytest.skip("Chromium not found: install Debian's `chromium` package (.ci/run does)")
    return path

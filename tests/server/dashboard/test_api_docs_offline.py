"""/docs and /redoc load their scripts and styles from the service itself (the fastapi-offline
package), so that they render on a machine without internet (in a browser with every outside
request refused: test_dashboard_browser_views.py), and stay open when reads need a token."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.security import DOCS_ASSETS
from server.settings import Settings


def _asset_urls(html: str) -> list[str]:
    return re.findall(r'(?:src|href)=["\']([^"\']+)["\']', html)


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_docs_pages_name_only_local_assets_which_are_served(app_client: Any, page: str) -> None:
    html = app_client.get(page).text
    urls = [u for u in _asset_urls(html) if u.endswith((".js", ".css"))]
    assert urls and all(u.startswith(f"{DOCS_ASSETS}/") for u in urls), urls
    assert "://" not in " ".join(_asset_urls(html))
    for url in urls:
        response = app_client.get(url)
        assert response.status_code == 200 and len(response.content) > 1000, url


def test_docs_assets_stay_open_when_reads_need_a_token(tmp_path: Path) -> None:
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'kb.sqlite'}",
        token="s3cret",
        tokens_file=None,
        auth_reads=True,
    )
    with TestClient(create_app(settings)) as client:
        assert client.get("/v1/kbs").status_code == 401
        assert client.get("/docs").status_code == 200
        assert client.get(f"{DOCS_ASSETS}/swagger-ui.css").status_code == 200

"""/login answers odd forms with a clear 4xx, never a 500, and never echoes a token it was
sent back as a cookie unless it is the server's own (on a server without a token: none)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlencode

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import Settings

TOKEN = "s3cret"
FORM = {"content-type": "application/x-www-form-urlencoded"}


def service(db: Path, token: str | None) -> TestClient:
    settings = Settings(database_url=f"sqlite:///{db}", token=token, surrogate_enabled=False)
    return TestClient(create_app(settings), follow_redirects=False, raise_server_exceptions=False)


@pytest.fixture(params=[None, TOKEN], ids=["open", "guarded"])
def login(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[TestClient]:
    with service(tmp_path / "kb.sqlite", request.param) as client:
        yield client


def post_form(client: TestClient, body: str) -> object:
    return client.post("/login", content=body.encode("utf-8"), headers=FORM)


def test_more_than_four_fields_is_a_400(login: TestClient) -> None:
    body = urlencode([("token", TOKEN), ("next", "/")] + [(f"f{i}", "x") for i in range(5)])
    response = post_form(login, body)
    assert response.status_code == 400, response.text
    assert "set-cookie" not in response.headers


def test_a_token_that_is_not_latin1_is_never_a_500(login: TestClient) -> None:
    response = post_form(login, urlencode({"token": "ключ-密钥", "next": "/"}))
    assert response.status_code in (303, 401), response.text
    assert "set-cookie" not in response.headers


def test_a_huge_token_is_refused_and_never_echoed(login: TestClient) -> None:
    response = post_form(login, urlencode({"token": "t" * 1_000_000, "next": "/"}))
    assert response.status_code == 413
    assert "set-cookie" not in response.headers and len(response.content) < 1000


def test_an_open_server_sets_no_cookie_and_a_guarded_one_only_its_token(tmp_path: Path) -> None:
    with service(tmp_path / "open.sqlite", None) as open_server:
        response = post_form(open_server, urlencode({"token": "anything", "next": "/x"}))
        assert response.status_code == 303 and "set-cookie" not in response.headers
    with service(tmp_path / "guarded.sqlite", TOKEN) as guarded:
        response = post_form(guarded, urlencode({"token": TOKEN, "next": "/x"}))
        assert (
            response.status_code == 303 and f"cpkb_token={TOKEN}" in response.headers["set-cookie"]
        )

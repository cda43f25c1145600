"""server.security on its own: token files, constant-time matching, route classification,
the app-wide dependency, the body-size limit and CORS, on a minimal app with the same routes."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi import Depends, FastAPI
from fastapi.testclient import TestClient

from server import security
from server.security import AccessPolicy, SecurityConfigError, bearer_scheme, install_security
from server.settings import Settings


def test_tokens_file_skips_blank_lines_and_comments(tmp_path: Path) -> None:
    path = tmp_path / "tokens"
    path.write_text("# lab tokens\n\n alpha \nbeta\n# old: gamma\n")
    assert security.read_tokens_file(path) == ["alpha", "beta"]


@pytest.mark.parametrize("content", [None, "", "# only a comment\n\n"])
def test_unusable_tokens_file_fails_at_start(tmp_path: Path, content: str | None) -> None:
    path = tmp_path / "tokens"
    if content is not None:
        path.write_text(content)
    with pytest.raises(SecurityConfigError, match="tokens file"):
        AccessPolicy.from_settings(Settings(token=None, tokens_file=path))


def test_policy_merges_env_token_and_file(tmp_path: Path) -> None:
    path = tmp_path / "tokens"
    path.write_text("from-file\n")
    policy = AccessPolicy.from_settings(Settings(token="from-env", tokens_file=path))
    assert policy.accepts("from-env") and policy.accepts("from-file")
    assert not policy.accepts("from-fil") and not policy.accepts("from-env ")
    assert not policy.accepts(None) and not policy.accepts("")


def test_blank_token_means_no_protection() -> None:
    assert not AccessPolicy.from_settings(Settings(token="  ")).enabled


def test_every_token_compared_in_constant_time(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[bytes, bytes]] = []
    real = security.hmac.compare_digest

    def spy(a: bytes, b: bytes) -> bool:
        calls.append((a, b))
        return real(a, b)

    monkeypatch.setattr(security.hmac, "compare_digest", spy)
    policy = AccessPolicy.from_tokens(["first", "second", "third"])
    assert policy.accepts("first")
    assert len(calls) == 3, "no early exit on a match: timing must not tell which token matched"
    assert policy.accepts("ünïcode") is False


@pytest.mark.parametrize(
    ("method", "path", "write"),
    [
        ("GET", "/v1/kbs", False),
        ("HEAD", "/v1/kbs/{kb}/types", False),
        ("POST", "/v1/kbs/{kb}/types/match", False),
        ("POST", "/v1/kbs/{kb}/types/{type_id}/predict", False),
        ("POST", "/v1/kbs/{kb}/suggest", False),
        ("POST", "/v1/kbs", True),
        ("POST", "/v1/kbs/{kb}/points", True),
        ("DELETE", "/v1/kbs/{kb}", True),
        ("PUT", "/v1/kbs/{kb}/anything-new", True),
        ("POST", "/v1/kbs/{kb}/types/{type_id}/fit", True),
    ],
)
def test_routes_are_writes_unless_known_reads(method: str, path: str, write: bool) -> None:
    assert security.is_write(method, path) is write


def make_app(**settings: object) -> FastAPI:
    app = FastAPI(dependencies=[Depends(bearer_scheme)])

    @app.get("/healthz")
    def health() -> dict:
        return {"status": "ok"}

    @app.get("/v1/kbs")
    def kbs() -> list:
        return []

    @app.post("/v1/kbs", status_code=201)
    def create(body: dict) -> dict:
        return {"n_bytes": len(str(body))}

    @app.post("/v1/kbs/{kb}/suggest")
    def suggest(kb: str) -> dict:
        return {"kb": kb}

    @app.delete("/v1/kbs/{kb}", status_code=204)
    def delete(kb: str) -> None:
        return None

    install_security(app, Settings(**settings))
    return app


def test_open_server_needs_no_token() -> None:
    with TestClient(make_app()) as client:
        assert client.post("/v1/kbs", json={"name": "a"}).status_code == 201
        assert client.delete("/v1/kbs/a").status_code == 204


def test_token_guards_writes_and_deletes_only() -> None:
    with TestClient(make_app(token="s3cret")) as client:
        for response in (client.post("/v1/kbs", json={}), client.delete("/v1/kbs/a")):
            assert response.status_code == 401
            assert response.headers["www-authenticate"].startswith("Bearer")
            assert "token" in response.json()["detail"]
        wrong = {"Authorization": "Bearer s3cret2"}
        assert client.delete("/v1/kbs/a", headers=wrong).status_code == 401
        assert client.delete("/v1/kbs/a", headers={"Authorization": "s3cret"}).status_code == 401
        right = {"Authorization": "Bearer s3cret"}
        assert client.delete("/v1/kbs/a", headers=right).status_code == 204
        assert client.get("/v1/kbs").status_code == 200
        assert client.post("/v1/kbs/a/suggest").status_code == 200


def test_auth_reads_guards_reads_but_not_health() -> None:
    with TestClient(make_app(token="s3cret", auth_reads=True)) as client:
        assert client.get("/v1/kbs").status_code == 401
        assert client.post("/v1/kbs/a/suggest").status_code == 401
        ok = {"Authorization": "Bearer s3cret"}
        assert client.get("/v1/kbs", headers=ok).status_code == 200
        assert client.get("/healthz").status_code == 200
        assert client.get("/openapi.json").status_code == 200


def test_oversized_body_is_413_with_or_without_content_length() -> None:
    app = make_app(max_body_bytes=2048)
    with TestClient(app) as client:
        assert client.post("/v1/kbs", json={"x": "a" * 1000}).status_code == 201
        declared = client.post("/v1/kbs", json={"x": "a" * 5000})
        assert declared.status_code == 413
        assert "CPKB_MAX_BODY_BYTES" in declared.json()["detail"]

        def chunks():
            yield b'{"x": "'
            for _ in range(10):
                yield b"a" * 500
            yield b'"}'

        chunked = client.post(
            "/v1/kbs", content=chunks(), headers={"content-type": "application/json"}
        )
        assert chunked.status_code == 413


def test_body_under_limit_arrives_intact_when_chunked() -> None:
    app = make_app(max_body_bytes=4096)

    def chunks():
        yield b'{"x": "'
        for _ in range(4):
            yield b"b" * 500
        yield b'"}'

    with TestClient(app) as client:
        response = client.post(
            "/v1/kbs", content=chunks(), headers={"content-type": "application/json"}
        )
    assert response.status_code == 201
    assert response.json()["n_bytes"] == len(str({"x": "b" * 2000}))


def test_cors_is_off_by_default_and_on_when_configured() -> None:
    preflight = {
        "Origin": "https://evil.example",
        "Access-Control-Request-Method": "POST",
    }
    with TestClient(make_app()) as client:
        response = client.options("/v1/kbs", headers=preflight)
        assert "access-control-allow-origin" not in response.headers
        get = client.get("/v1/kbs", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in get.headers
    allowed = make_app(cors_origins=["https://lab.example"])
    with TestClient(allowed) as client:
        response = client.get("/v1/kbs", headers={"Origin": "https://lab.example"})
        assert response.headers["access-control-allow-origin"] == "https://lab.example"
        response = client.get("/v1/kbs", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in response.headers


def test_default_bind_is_loopback() -> None:
    assert Settings().host == "127.0.0.1"


def test_browser_login_sets_a_cookie_that_reads_accept_and_writes_do_not() -> None:
    with TestClient(make_app(token="s3cret", auth_reads=True), follow_redirects=False) as client:
        page = client.get("/v1/kbs", headers={"Accept": "text/html"})
        assert page.status_code == 303
        assert page.headers["location"] == "/login?next=/v1/kbs"
        assert "password" in client.get("/login", params={"next": "/v1/kbs"}).text
        wrong = client.post("/login", data={"token": "nope", "next": "/v1/kbs"})
        assert wrong.status_code == 401 and "cpkb_token" not in wrong.headers.get("set-cookie", "")
        right = client.post("/login", data={"token": "s3cret", "next": "/v1/kbs"})
        assert right.status_code == 303 and right.headers["location"] == "/v1/kbs"
        cookie = right.headers["set-cookie"].lower()
        assert "httponly" in cookie and "samesite=strict" in cookie
        assert client.get("/v1/kbs").status_code == 200
        assert client.post("/v1/kbs", json={}).status_code == 401, "a cookie must never write"
        assert client.post("/logout").status_code == 303
        assert client.get("/v1/kbs").status_code == 401


def test_login_never_redirects_to_another_site() -> None:
    with TestClient(make_app(token="s3cret"), follow_redirects=False) as client:
        for target in ("//evil.example/x", "https://evil.example", "javascript:alert(1)"):
            response = client.post("/login", data={"token": "s3cret", "next": target})
            assert response.headers["location"] == "/"
        page = client.get("/login", params={"next": "'><script>alert(1)</script>"})
        assert "<script>" not in page.text

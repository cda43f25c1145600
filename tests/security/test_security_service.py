"""The token on the real service: every write route of the app needs it, reads follow the
setting, and the client, the CLI and `cpkb serve` handle it, against a real server."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from client import CpkbClient, Unauthorized
from cpkb.cli import main as cpkb_main
from cpkb.embedded import embedded_service
from server.app import create_app
from server.security import OPEN_PATHS, is_write
from server.settings import Settings

TOKEN = "correct-horse-battery-staple"
GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Inv-kin"},
        {
            "id": "d",
            "role": "decision",
            "label": "#dir",
            "domain": {"kind": "categorical", "choices": ["front", "top"]},
        },
    ],
    "edges": [{"source": "d", "target": "f", "label": "feeds"}],
}
POINT = {"graph": GRAPH, "x": {"#dir": "top"}, "feasible": True}


def app_settings(db: Path, **overrides: object) -> Settings:
    base = {"database_url": f"sqlite:///{db}", "token": TOKEN, "tokens_file": None}
    return Settings(**(base | overrides))


def routes(app: FastAPI) -> list[tuple[str, str, str]]:
    """Every (method, path template, concrete path) of the app's documented API."""
    found = []
    for template, operations in app.openapi()["paths"].items():
        path = template.replace("{kb}", "default")
        path = re.sub(r"\{[^}]+\}", "0123abcd", path)
        found += [(method.upper(), template, path) for method in operations]
    return found


@pytest.fixture
def guarded(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(app_settings(tmp_path / "kb.sqlite"))) as client:
        yield client


def test_every_write_route_of_the_app_needs_the_token(guarded: TestClient) -> None:
    writes = [(m, t, p) for m, t, p in routes(guarded.app) if is_write(m, t)]
    assert {("POST", "/v1/kbs"), ("DELETE", "/v1/kbs/{kb}"), ("POST", "/v1/kbs/{kb}/points")} <= {
        (m, t) for m, t, _ in writes
    }
    for method, _, path in writes:
        for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": TOKEN}):
            response = guarded.request(method, path, json={}, headers=headers)
            assert response.status_code == 401, (method, path, headers, response.text)


def test_reads_stay_open_and_writes_work_with_the_token(guarded: TestClient) -> None:
    auth = {"Authorization": f"Bearer {TOKEN}"}
    assert (
        guarded.post("/v1/kbs/default/points", json={"points": [POINT]}, headers=auth).status_code
        == 201
    )
    for method, template, path in routes(guarded.app):
        if not is_write(method, template) and method == "GET":
            assert guarded.get(path).status_code != 401, path
    assert guarded.get("/v1/kbs").json()[0]["n_points"] == 1
    assert guarded.delete("/v1/kbs/default").status_code == 401
    assert guarded.get("/v1/kbs").json()[0]["n_points"] == 1, "a refused delete changed data"


def test_auth_reads_guards_every_route_but_health_and_docs(tmp_path: Path) -> None:
    app = create_app(app_settings(tmp_path / "kb.sqlite", auth_reads=True))
    with TestClient(app) as client:
        for method, template, path in routes(app):
            response = client.request(method, path, json={})
            if template in OPEN_PATHS:
                assert response.status_code == 200, path
            else:
                assert response.status_code == 401, (method, path)
        assert (
            client.get("/v1/kbs", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200
        )


def test_unauthenticated_write_does_not_reveal_what_exists(guarded: TestClient) -> None:
    known = guarded.post("/v1/kbs/default/points", json={"points": [POINT]})
    unknown = guarded.post("/v1/kbs/no-such-kb/points", json={"points": [POINT]})
    assert known.status_code == unknown.status_code == 401
    assert known.json() == unknown.json()


@pytest.fixture(scope="module")
def server_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """One real server for the module (a start costs seconds), guarded by a tokens file."""
    tmp = tmp_path_factory.mktemp("guarded")
    tokens = tmp / "tokens"
    tokens.write_text(f"# lab\n{TOKEN}\nsecond-token\n")
    env = {"CPKB_TOKENS_FILE": str(tokens), "CPKB_SURROGATE__ENABLED": "false"}
    with embedded_service(f"sqlite:///{tmp / 'kb.sqlite'}", env=env) as url:
        yield url


@pytest.mark.slow
def test_client_sends_its_token_to_a_real_server(server_url: str) -> None:
    with CpkbClient(server_url, retries=0) as anonymous:
        assert anonymous.list_kbs()[0].name == "default"
        with pytest.raises(Unauthorized, match="token"):
            anonymous.post_points("default", [POINT])
        with pytest.raises(Unauthorized):
            anonymous.delete_kb("default")
    for token in (TOKEN, "second-token"):
        with CpkbClient(server_url, token=token, retries=0) as client:
            assert len(client.post_points("default", [POINT])) == 1
    with (
        CpkbClient(server_url, token="second-token-", retries=0) as wrong,
        pytest.raises(Unauthorized, match="invalid token"),
    ):
        wrong.create_kb("nope")


@pytest.mark.slow
def test_cli_passes_the_token_from_option_or_environment(
    server_url: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("CPKB_TOKEN", raising=False)
    assert (
        cpkb_main(["kb", "create", "lab1", "--url", server_url]) == 3
    )  # refused: the knowledge base exit, as plan and bench give
    assert "token" in capsys.readouterr().err
    assert cpkb_main(["kb", "create", "lab1", "--url", server_url, "--token", TOKEN]) == 0
    monkeypatch.setenv("CPKB_TOKEN", "second-token")
    assert cpkb_main(["kb", "delete", "lab1", "--url", server_url]) == 0
    assert "deleted" in capsys.readouterr().out
    assert cpkb_main(["kb", "list", "--url", server_url]) == 0
    assert "lab1" not in capsys.readouterr().out


@pytest.mark.slow
def test_serve_refuses_an_unreadable_tokens_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import uvicorn

    def started(*_: object, **__: object) -> None:
        raise AssertionError("the server started without its tokens file")

    monkeypatch.setattr(uvicorn, "run", started)
    monkeypatch.setenv("CPKB_TOKENS_FILE", str(tmp_path / "missing"))
    assert cpkb_main(["serve", "--db", f"sqlite:///{tmp_path / 'kb.sqlite'}"]) == 2
    err = capsys.readouterr().err
    assert "tokens file" in err and "Traceback" not in err

"""No route takes a non-finite number in, on either backend; a NaN stored by an older version
(SQLite kept one in a found binding) does not break the readers of the rows beside it."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import httpx
import pytest
from cli_support import cpkb_in_process
from service_support import make_point, run_live_server

from client import CpkbClient, CpkbError
from server.db import Store
from server.orm import BindingRow

KB = "/v1/kbs/default"
GOOD_BINDING = {"task": "desk", "skeleton": "s" * 64, "bindings": {"#pose": [0.5, 0.5]}}


def post_text(client: Any, path: str, text: str) -> Any:
    return client.post(path, content=text, headers={"content-type": "application/json"})


def bodies(type_id: str) -> dict[str, tuple[str, str]]:
    """A request of each route that takes numbers, with `NUMBER` where a number goes."""
    pose = {"kind": "continuous", "low": [0.0], "high": [1.0]}
    return {
        "bindings": ("/bindings", json.dumps({**GOOD_BINDING, "bindings": {"#p": ["NUMBER"]}})),
        "suggest fixed": (
            "/suggest",
            json.dumps({"space": {"q": pose}, "fixed": {"p": ["NUMBER"]}}),
        ),
        "suggest exclude": (
            "/suggest",
            json.dumps({"space": {"q": pose}, "exclude": [{"q": ["NUMBER"]}]}),
        ),
        "points": (
            "/points",
            json.dumps({"points": [make_point(1) | {"x": {"#dir": "top", "#pose": ["NUMBER"]}}]}),
        ),
        "predict": (
            f"/types/{type_id}/predict",
            json.dumps({"x": [{"#dir": "top", "#pose": ["NUMBER", 0.5, 0.5]}]}),
        ),
    }


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_every_route_refuses_a_non_finite_number(app_client: Any, number: str) -> None:
    posted = app_client.post(f"{KB}/points", json={"points": [make_point(1)]})
    type_id = posted.json()["results"][0]["type_id"]
    for name, (path, body) in bodies(type_id).items():
        response = post_text(app_client, KB + path, body.replace('"NUMBER"', number))
        assert response.status_code == 422, (name, response.status_code, response.text[:300])
        json.loads(response.text)  # the refusal itself is valid JSON
    assert app_client.get(f"{KB}/bindings").json()["bindings"] == []


def poison(db_url: str) -> None:
    """A binding holding NaN, as versions before the refusal let SQLite store it."""
    store = Store.from_url(db_url)
    try:
        with store.transaction(write=True) as session:
            kb_pk = session.scalar(select_default_kb())
            session.add(
                BindingRow(
                    kb_id=kb_pk,
                    task="desk",
                    skeleton="s" * 64,
                    bindings={"#pose": [math.nan, 0.5]},
                )
            )
    finally:
        store.dispose()


def select_default_kb() -> Any:
    from sqlalchemy import select

    from server.orm import KnowledgeBaseRow

    return select(KnowledgeBaseRow.id).where(KnowledgeBaseRow.name == "default")


@pytest.mark.slow
def test_a_stored_nan_binding_is_skipped_by_every_reader(
    sqlite_url: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    with run_live_server(sqlite_url, tmp_path / "server.log") as server:
        http = httpx.Client(base_url=server.url, timeout=30)
        assert http.post(f"{KB}/bindings", json=GOOD_BINDING).status_code == 201
        poison(sqlite_url)
        assert http.post(f"{KB}/bindings", json=GOOD_BINDING).status_code == 201
        page = http.get(f"{KB}/bindings")
        listed = cpkb_in_process(capfd, "bindings", "--url", server.url)
        http.close()
        with CpkbClient(server.url) as kb:
            found = kb.bindings("default")
    assert page.status_code == 200, page.text
    assert [b["binding_id"] for b in page.json()["bindings"]] == [1, 3]
    assert page.json()["cursor"] == 3
    assert [b.binding_id for b in found.bindings] == [1, 3]
    assert listed.returncode == 0 and "Traceback" not in listed.stderr, listed.stderr
    assert listed.stdout.count("#pose=[0.5, 0.5]") == 2
    assert "binding 2 skipped" in (tmp_path / "server.log").read_text()


def test_an_answer_the_client_cannot_read_is_one_error_line() -> None:
    """An older service answers a stored NaN as null: the client raises its own error."""
    poisoned = {
        "bindings": [
            {"binding_id": 2, "task": "desk", "skeleton": "s", "bindings": {"#p": [None]}}
        ],
        "cursor": 2,
    }
    transport = httpx.MockTransport(lambda _: httpx.Response(200, json=poisoned))
    with (
        CpkbClient("http://old", transport=transport) as kb,
        pytest.raises(CpkbError, match="does not fit the wire contract") as raised,
    ):
        kb.bindings("default")
    assert "\n" not in str(raised.value)

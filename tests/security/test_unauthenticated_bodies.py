"""A token-protected service refuses an unauthenticated write before it reads the body: the
401 arrives while the client is still to send almost all of a large upload."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import pytest
from service_support import LiveServer, make_point, run_live_server

TOKEN = "correct-horse-battery-staple"
# Long enough for a loaded machine; a server that waits for the body never answers at all.
ANSWER_TIMEOUT_S = 120


@pytest.fixture
def guarded_server(db_url: str, tmp_path: Path) -> Iterator[LiveServer]:
    with run_live_server(db_url, tmp_path / "server.log", env={"CPKB_TOKEN": TOKEN}) as server:
        yield server


def first_answer_line(url: str, head: str, body_start: bytes) -> str:
    """Send a request's head and the first bytes of its body, then read the status line."""
    parts = urlsplit(url)
    with socket.create_connection((parts.hostname, parts.port), timeout=ANSWER_TIMEOUT_S) as sock:
        sock.sendall(head.encode("ascii") + b"\r\n" + body_start)
        received = b""
        while b"\r\n" not in received:
            chunk = sock.recv(4096)
            if not chunk:
                break
            received += chunk
    return received.split(b"\r\n", 1)[0].decode("ascii", "replace")


@pytest.mark.slow
@pytest.mark.parametrize("framing", ["content-length", "chunked"])
def test_an_unauthenticated_upload_is_refused_before_its_body(
    guarded_server: LiveServer, framing: str
) -> None:
    host = urlsplit(guarded_server.url).netloc
    length = (
        "Content-Length: 30000000" if framing == "content-length" else "Transfer-Encoding: chunked"
    )
    head = (
        f"POST /v1/kbs/default/points HTTP/1.1\r\nHost: {host}\r\n"
        f"Content-Type: application/json\r\n{length}\r\n"
    )
    start = b'{"points": [' if framing == "content-length" else b'c\r\n{"points": [\r\n'
    assert first_answer_line(guarded_server.url, head, start).split()[1] == "401"
    with httpx.Client(base_url=guarded_server.url, timeout=60) as http:
        auth = {"Authorization": f"Bearer {TOKEN}"}
        stored = http.post("/v1/kbs/default/points", json={"points": [make_point(1)]}, headers=auth)
        assert stored.status_code == 201, stored.text
        assert http.get("/v1/kbs/default").json()["n_points"] == 1

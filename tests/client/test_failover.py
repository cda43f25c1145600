"""The client given several replicas' URLs: a replica that cannot be reached or answers 503 is
passed over for the next one, and a post re-sent there stores its points once."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from service_support import LiveServer, make_point, run_live_server

from client import CpkbClient, ServiceUnavailable, split_urls
from cpkb.cli import CliError
from cpkb.cli.reach import checked_url


def free_port() -> int:
    """A loopback port nothing listens on (bound, then let go)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    """One live service (failing over is the client's part: any backend does)."""
    tmp: Path = tmp_path_factory.mktemp("failover")
    with run_live_server(f"sqlite:///{tmp / 'kb.sqlite'}", tmp / "server.log") as live:
        yield live


@pytest.mark.slow
def test_a_dead_replica_is_passed_over(server: LiveServer) -> None:
    dead = f"http://127.0.0.1:{free_port()}"
    with CpkbClient(f"{dead},{server.url}", retries=1, backoff=0.01) as client:
        results = client.post_points("default", [make_point(i) for i in range(3)])
        assert client.base_url == server.url  # it stays with the replica that answered
        again = client.post_points("default", [make_point(5, key="failover-5")])
    assert [r.point_id for r in results] == sorted(r.point_id for r in results)
    assert again[0].type_id == results[0].type_id


@pytest.mark.slow
def test_a_replica_answering_503_is_passed_over(server: LiveServer) -> None:
    """The first replica's answers are a 503 of a router in front of it (the one part that is
    not real here); the second is a real service."""
    real = httpx.HTTPTransport()

    def route(request: httpx.Request) -> httpx.Response:
        if request.url.host == "draining.invalid":
            return httpx.Response(503, json={"detail": "draining"})
        return real.handle_request(request)

    transport = httpx.MockTransport(route)
    urls = f"http://draining.invalid,{server.url}"
    with CpkbClient(urls, retries=0, transport=transport) as client:
        assert client.health().status == "ok"
    with (
        CpkbClient("http://draining.invalid", retries=1, backoff=0.01, transport=transport) as c,
        pytest.raises(ServiceUnavailable),
    ):
        c.health()


def test_every_replica_down_names_them_all() -> None:
    urls = [f"http://127.0.0.1:{free_port()}" for _ in range(2)]
    with (
        CpkbClient(urls, retries=1, backoff=0.01, reconnect_for=0) as client,
        pytest.raises(ServiceUnavailable, match="any of " + ", ".join(urls)),
    ):
        client.list_kbs()


def test_split_urls_and_the_cli_check() -> None:
    assert split_urls("http://a:1/, http://b:2") == ["http://a:1", "http://b:2"]
    with pytest.raises(ValueError):
        split_urls(" , ")
    assert checked_url("http://a:1,https://b") == "http://a:1,https://b"
    with pytest.raises(CliError, match="'b:2' is not an http"):
        checked_url("http://a:1,b:2")
    with pytest.raises(CliError, match="empty URL"):
        checked_url("http://a:1,")

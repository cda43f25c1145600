"""The client's reconnect budget: long waits only for a server it has reached before."""

from __future__ import annotations

import time

import pytest
from killable_server import free_port

from client import CpkbClient, ServiceUnavailable


def test_a_server_never_reached_fails_after_the_counted_retries() -> None:
    url = f"http://127.0.0.1:{free_port()}"
    start = time.monotonic()
    with (
        CpkbClient(url, retries=2, backoff=0.01, reconnect_for=60) as client,
        pytest.raises(ServiceUnavailable, match="cannot reach"),
    ):
        client.list_kbs()
    assert time.monotonic() - start < 30, "a wrong URL must not wait out the reconnect budget"

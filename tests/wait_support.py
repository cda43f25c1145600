"""Waiting in tests on what a test needs to see, not on a clock a loaded machine can miss."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

# Long enough that only a hang reaches it: two busy cores slow a fit or a start tenfold.
PATIENCE_S = 120.0


def wait_until(
    predicate: Callable[[], T],
    *,
    timeout: float = PATIENCE_S,
    interval: float = 0.05,
    what: str = "the condition",
) -> T:
    """Poll `predicate` until it returns something truthy, and return that; fail after
    `timeout` seconds with an AssertionError naming `what`."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"{what} did not happen within {timeout:g} s")
        time.sleep(interval)

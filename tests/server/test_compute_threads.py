"""The service computes each request on one BLAS thread: its requests already run in threads of
their own, and BLAS's threads on top of them spin for cores that other work holds."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch
from suggest_support import make_client
from threadpoolctl import OpenBLASController, threadpool_info, threadpool_limits


def _blas_threads() -> set[int]:
    return {int(p["num_threads"]) for p in threadpool_info() if p["user_api"] == "blas"}


def _set(blas: int, intra: int) -> None:
    OpenBLASController.clear_controlling_thread(force=True)
    threadpool_limits(blas, user_api="blas")
    torch.set_num_threads(intra)


@pytest.fixture
def two_threads() -> Iterator[None]:
    """BLAS (and this thread's torch) on two threads, as on a 2-core machine; as they were
    after the test."""
    blas, intra = min(_blas_threads()), torch.get_num_threads()
    _set(2, 2)
    yield
    _set(blas, intra)


def test_the_service_runs_blas_on_one_thread(sqlite_url: str, two_threads: None) -> None:
    assert _blas_threads() == {2}
    with make_client(sqlite_url):
        assert _blas_threads() == {1}

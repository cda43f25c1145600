"""The engine's fit worker: a child process of its own that answers fits, passes their errors on,
and ends at once when told to (a fit in flight then fails with WorkerDied, it does not hang)."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import numpy as np
import pytest

from server.surrogates.worker import ChildProcessFitter, ThreadFitter, WorkerDied


def _points(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    z = rng.random((n, 3))
    return z, z[:, 0] > 0.5


@pytest.fixture
def child() -> Iterator[ChildProcessFitter]:
    fitter = ChildProcessFitter(threads=1)
    yield fitter
    fitter.terminate()


@pytest.mark.slow
def test_a_child_process_fits_as_a_thread_does(child: ChildProcessFitter) -> None:
    z, y = _points(40)
    there = child.fit(z, y, 0, None, 16)
    here = ThreadFitter()
    try:
        local = here.fit(z, y, 0, None, 16)
    finally:
        here.terminate()
    assert there.kind == local.kind == "vgp" and there.n_fitted == 40
    # Fits train in float32: another process sums in another order (its own BLAS threads), and
    # sixty Adam steps carry the rounding a few thousandths apart. The same model otherwise.
    np.testing.assert_allclose(there.predictor.proba(z), local.predictor.proba(z), atol=0.02)
    assert ((there.predictor.proba(z) > 0.5) == (local.predictor.proba(z) > 0.5)).all()


@pytest.mark.slow
def test_a_failed_fit_raises_its_error_and_the_worker_stays(child: ChildProcessFitter) -> None:
    z, y = _points(40)
    with pytest.raises(ValueError, match="40 points and 30 labels"):
        child.fit(z, y[:30], 0, None, 16)  # labels that do not match the points
    assert child.fit(z, y, 0, None, 16).n_fitted == 40


def test_terminate_ends_a_fit_in_flight(child: ChildProcessFitter) -> None:
    z, y = _points(3000)
    outcome: list[BaseException | object] = []
    started = threading.Event()

    def fit() -> None:
        started.set()
        try:
            outcome.append(child.fit(z, y, 0, None, 128))
        except BaseException as exc:
            outcome.append(exc)

    thread = threading.Thread(target=fit)
    thread.start()
    assert started.wait(60)
    child.terminate()
    thread.join(timeout=120)
    assert not thread.is_alive()
    assert len(outcome) == 1 and isinstance(outcome[0], WorkerDied)
    with pytest.raises(WorkerDied):
        child.fit(z, y, 0, None, 128)

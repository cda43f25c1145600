"""What replicas share through the database, piece by piece: the pending book and the stored
fits with their claims (the two-replica service is in tests/reliability/test_replicas.py)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest
from service_support import make_graph, make_point

from contract.models import PointIn
from server.db import Store
from server.schema import prepare_database
from server.services.points import add_points
from server.services.types import load_training_points
from server.settings import ServiceSurrogateConfig
from server.surrogates.engine import SurrogateEngine
from server.surrogates.pending_db import DatabasePendingBook
from server.surrogates.shared import FitShare
from surrogate.encoding import SpaceEncoder
from surrogate.models import fit_classifier


@pytest.fixture
def store(db_url: str) -> Iterator[Store]:
    store = Store.from_url(db_url)
    prepare_database(store)
    yield store
    store.dispose()


def test_the_pending_book_is_shared_and_answered(store: Store) -> None:
    mine, theirs = DatabasePendingBook(store, 30.0), DatabasePendingBook(store, 30.0)
    bind = {"#pose": "p", "#dir": "d"}
    mine.add("default", {"p": [0.1, 0.2, 0.0], "d": "top"}, [("T1", bind)])
    mine.add("default", {"q": 0.5}, [])
    assert theirs.count("default") == 2
    assert theirs.for_request("default", frozenset({"T1"})) == [{"p": [0.1, 0.2, 0.0], "d": "top"}]
    assert theirs.for_request("default", frozenset()) == [{"q": 0.5}]
    assert theirs.for_request("default", frozenset({"T2"})) == []
    # A point of T1 elsewhere answers nothing; at the suggested values it answers the entry.
    assert theirs.answered("default", "T1", [{"#pose": [0.9, 0.2, 0.0], "#dir": "top"}]) == 0
    assert theirs.answered("default", "T1", [{"#pose": [0.1, 0.2, 0.0], "#dir": "top"}]) == 1
    assert mine.for_request("default", frozenset({"T1"})) == []


def test_pending_entries_expire(store: Store) -> None:
    book = DatabasePendingBook(store, 0.05)
    book.add("default", {"q": 0.5}, [])
    time.sleep(0.2)
    assert book.for_request("default", frozenset()) == []
    # A lifetime a busy machine outlasts, so that only the expired row can be missing.
    book.ttl_s = 60.0
    book.add("default", {"q": 0.7}, [])  # and the expired row is gone from the table
    assert book.count("default") == 1


def _type_pk(store: Store) -> int:
    """The row id of a type with a few points in `default`."""
    graph = make_graph()
    points = [PointIn.model_validate(make_point(i, graph=graph)) for i in range(12)]
    type_id = add_points(store, "default", points).results[0].type_id
    return load_training_points(store, "default", type_id).origin[0]


def _type_id(store: Store) -> str:
    return (
        add_points(store, "default", [PointIn.model_validate(make_point(99, graph=make_graph()))])
        .results[0]
        .type_id
    )


@pytest.mark.slow
def test_a_stored_fit_loads_as_it_was_saved(store: Store) -> None:
    pk = _type_pk(store)
    rng = np.random.default_rng(0)
    z = rng.random((40, 3))
    fit = fit_classifier(z, z[:, 0] > 0.5, max_iters=10)
    a, b = FitShare(store, "a"), FitShare(store, "b")
    assert b.newer(pk, 0) is None
    assert a.save(pk, fit)
    stored = b.newer(pk, 0)
    assert stored is not None and stored.fitted_by == "a" and stored.fit.n_fitted == 40
    probe = rng.random((5, 3))
    assert np.allclose(stored.fit.predictor.proba(probe), fit.predictor.proba(probe))
    assert stored.fit.warm_state is not None and stored.fit.warm_state["m"] == fit.warm_state["m"]
    assert b.newer(pk, 40) is None
    # An older version never replaces a newer one.
    older = fit_classifier(z[:30], z[:30, 0] > 0.5, max_iters=5)
    assert not b.save(pk, older)
    assert a.version(pk) == 40


def test_a_fit_for_a_deleted_type_is_not_stored_for_its_row_ids_next_type(store: Store) -> None:
    """A knowledge base deleted while its type was being fitted frees the type's row id, which
    SQLite gives to the next type: the late fit, made on another decision space, must not
    become that type's."""
    pk = _type_pk(store)
    made_for = load_training_points(store, "default", _type_id(store)).origin[1]
    z = np.random.default_rng(0).random((20, 3))
    fit = fit_classifier(z, z[:, 0] > 0.5, max_iters=5)
    share = FitShare(store, "a")
    assert not share.save(pk, fit, made_for.replace(year=made_for.year - 1))
    assert share.version(pk) == 0
    assert share.save(pk, fit, made_for)
    assert share.version(pk) == 20


@pytest.mark.postgres
def test_one_claim_per_type_across_replicas(postgres_url: str) -> None:
    store_a, store_b = Store.from_url(postgres_url), Store.from_url(postgres_url)
    try:
        prepare_database(store_a)
        pk = _type_pk(store_a)
        a, b = FitShare(store_a, "a"), FitShare(store_b, "b")
        with a.claim(pk) as got_a:
            assert got_a
            with b.claim(pk) as got_b:
                assert not got_b
            with b.claim(pk + 1) as other:
                assert other  # another type is free
        with b.claim(pk) as got_b:
            assert got_b  # released with the fit
    finally:
        store_a.dispose()
        store_b.dispose()


@pytest.mark.slow
def test_a_restarted_engine_serves_the_stored_fit_without_fitting(store: Store) -> None:
    """What a second replica (or the same service after a restart) does with a type the first
    has fitted: it loads that fit on its first request and fits nothing."""
    graph = make_graph()
    points = [PointIn.model_validate(make_point(i, graph=graph)) for i in range(30)]
    type_id = add_points(store, "default", points).results[0].type_id
    config = ServiceSurrogateConfig(fit_process=False, prefit_types=0)
    first = SurrogateEngine(store, config)
    first.start()
    try:
        first.model("default", type_id)
        assert first.wait_idle(120)
        assert first.fits == 1
        fitted = first.model("default", type_id)
    finally:
        first.stop()
    second = SurrogateEngine(store, config)
    try:
        served = second.model("default", type_id)
        assert (served.version, served.n_fitted) == (fitted.version, 30)
        assert second.wait_idle(120)
        assert (second.fits, second.adopted) == (0, 1)
        z = SpaceEncoder(served.space).encode_points([make_point(i)["x"] for i in range(40, 45)])
        assert np.allclose(served.predictor.proba(z), fitted.predictor.proba(z))
    finally:
        second.stop()


def test_a_fit_queued_while_the_engine_stops_does_not_restart_it(store: Store) -> None:
    """A request that queues a fit as the server shuts down must not start the engine again:
    that restart cleared the stop before the old threads saw it, and `stop` then waited for
    them to its timeout (a minute per shutdown) while new threads outlived the server."""
    graph = make_graph()
    points = [PointIn.model_validate(make_point(i, graph=graph)) for i in range(6)]
    type_id = add_points(store, "default", points).results[0].type_id
    engine = SurrogateEngine(store, ServiceSurrogateConfig(fit_process=False, prefit_types=0))
    engine.start()
    coordinator = engine._thread
    engine.stop()
    engine._enqueue(("default", type_id))
    assert engine._thread is None and engine._first_thread is None
    assert coordinator is not None and not coordinator.is_alive()
    engine.start()  # an explicit start (the lifespan's) still restarts it
    try:
        assert engine._thread is not None and engine._thread.is_alive()
    finally:
        engine.stop()

"""The engine's fit schedule over a real SQLite file and real fits: refits of one type coalesce,
the types a request waits on go first, and a new type gets a model at once even while the
background fitter is held up."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from service_support import make_graph
from suggest_support import make_client, post_points
from wait_support import wait_until


@contextmanager
def held_coordinator(engine: Any) -> Iterator[tuple[threading.Event, list]]:
    """Hold the coordinator on its next type (as a long fit of another type would) until the
    block ends; yields the event set once it is held and the keys it refreshed, in order."""
    held, release = threading.Event(), threading.Event()
    refreshed: list = []
    refresh: Callable[[Any], None] = engine._refresh

    def slow(key: Any) -> None:
        refreshed.append(key)
        if not held.is_set():
            held.set()
            release.wait(timeout=120)
        refresh(key)

    engine._refresh = slow
    try:
        yield held, refreshed
    finally:
        release.set()


def _post(client: Any, graph: dict, xs: list[tuple[float, bool]]) -> str:
    body = [
        {"graph": graph, "x": {"#dir": "top", "#pose": [v, 0.5, 0.0]}, "feasible": ok}
        for v, ok in xs
    ]
    answer = client.post("/v1/kbs/default/points", json={"points": body})
    assert answer.status_code == 201, answer.text
    return answer.json()["results"][0]["type_id"]


def _labelled(n: int, start: int = 0) -> list[tuple[float, bool]]:
    """`n` poses spread over [0, 1), feasible above 0.5."""
    values = [(start + i) * 37 % 97 / 97 for i in range(n)]
    return [(v, v > 0.5) for v in values]


@pytest.mark.slow
def test_queued_refits_of_one_type_run_as_one(sqlite_url: str) -> None:
    with make_client(sqlite_url, instant_fit_points=0) as client:
        engine = client.app.state.surrogates
        with held_coordinator(engine) as (held, refreshed):
            busy = _post(client, make_graph("Busy", ("a",)), _labelled(8))
            assert held.wait(timeout=120)
            target = make_graph("Target", ("b",))
            type_id = _post(client, target, _labelled(8))
            for i in range(10):
                _post(client, target, _labelled(3, start=10 + 3 * i))
        assert engine.wait_idle(timeout=300)
        keys = [key[1] for key in refreshed]
        assert keys == [busy, type_id] and engine.fits == 2
        state = client.get(f"/v1/kbs/default/types/{type_id}").json()["surrogate"]
        assert state["n_fitted"] == 38 and state["kind"] == "vgp"


@pytest.mark.slow
def test_a_type_a_request_waits_on_is_fitted_first(sqlite_url: str) -> None:
    with make_client(sqlite_url, instant_fit_points=0) as client:
        engine = client.app.state.surrogates
        graphs = [make_graph(f"F{i}", (f"c{i}",)) for i in range(4)]
        ids = [_post(client, g, _labelled(8)) for g in graphs]
        assert engine.wait_idle(timeout=300)
        with held_coordinator(engine) as (held, refreshed):
            _post(client, graphs[0], _labelled(4, start=20))
            assert held.wait(timeout=120)
            for graph in graphs[1:]:
                _post(client, graph, _labelled(4, start=20))
            asked = client.post(
                f"/v1/kbs/default/types/{ids[3]}/predict",
                json={"x": [{"#dir": "top", "#pose": [0.5, 0.5, 0.0]}]},
            )
            assert asked.status_code == 200
        assert engine.wait_idle(timeout=300)
        order = [key[1] for key in refreshed]
        assert order[:2] == [ids[0], ids[3]], order


@pytest.mark.slow
def test_a_new_type_has_a_model_at_once_while_a_long_fit_runs(sqlite_url: str) -> None:
    with make_client(sqlite_url) as client:
        engine = client.app.state.surrogates
        with held_coordinator(engine) as (held, _):
            post_points(client, 4)  # other types, whose fit holds the coordinator
            assert held.wait(timeout=120)
            type_id = _post(client, make_graph("New", ("d",)), _labelled(30))
            url = f"/v1/kbs/default/types/{type_id}"
            wait_until(
                lambda: client.get(url).json()["surrogate"]["n_fitted"] == 30,
                what="the instant first model",
            )
            state = client.get(url).json()["surrogate"]
            assert state["kind"] == "vgp" and state["iterations"] <= 30  # the instant lane's
            p = client.post(
                url + "/predict",
                json={"x": [{"#dir": "top", "#pose": [v, 0.5, 0.0]} for v in (0.1, 0.9)]},
            ).json()["p_feasible"]
            assert p[0] < 0.3 and p[1] > 0.7
        assert engine.wait_idle(timeout=300)
        assert not engine._entries[("default", type_id)].instant  # the background fit landed


@pytest.mark.slow
def test_a_fit_that_lags_far_behind_its_points_gets_an_instant_refit(sqlite_url: str) -> None:
    with make_client(sqlite_url, instant_refit_factor=2.0) as client:
        engine = client.app.state.surrogates
        graph = make_graph("Lagging", ("e",))
        type_id = _post(client, graph, _labelled(10))
        assert engine.wait_idle(timeout=300)
        entry = engine._entries[("default", type_id)]
        first = entry.background
        assert first is not None and entry.n_fitted == 10 and not entry.instant
        warms: list = []
        fit = engine._fit

        def recording(z: Any, y: Any, warm: Any) -> Any:
            warms.append(warm)
            return fit(z, y, warm)

        engine._fit = recording
        lane_idle = lambda: not engine._first and engine._first_busy is None  # noqa: E731
        with held_coordinator(engine) as (held, _):
            post_points(client, 4)  # other types, whose fit holds the coordinator
            assert held.wait(timeout=120)
            _post(client, graph, _labelled(8, start=10))  # 18 points: not yet twice 10
            wait_until(lane_idle, what="the instant lane to look at the type")
            assert entry.n_fitted == 10 and not entry.instant
            _post(client, graph, _labelled(12, start=18))  # 30 points: three times 10
            wait_until(lambda: entry.n_fitted == 30, what="the instant refit")
            assert entry.instant and entry.fit.iterations <= 30 and entry.background is first
            assert _version(client, type_id) == "30-instant"
        assert engine.wait_idle(timeout=300)
        assert entry.n_fitted == 30 and not entry.instant and entry.background is entry.fit
        assert any(warm is first for warm in warms)  # the background fit went on from its own
        assert _version(client, type_id) == "30"  # another version: planners fetch it anew


def _version(client: Any, type_id: str) -> str:
    answer = client.post("/v1/kbs/default/models", json={"type_ids": [type_id]})
    assert answer.status_code == 200, answer.text
    return answer.json()["models"][0]["version"]

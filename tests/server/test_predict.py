"""POST /v1/kbs/{kb}/types/{type_id}/predict over a real SQLite file and real fits."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from suggest_support import make_client, post_points


@pytest.mark.slow
def test_predict_answers_probabilities_or_a_clear_4xx(client: Any) -> None:
    type_ids = post_points(client, 20)
    assert client.app.state.surrogates.wait_idle(timeout=300)
    url = f"/v1/kbs/default/types/{type_ids[0]}/predict"
    xs = [{"#dir": "top", "#pose": [0.9, 0.2, 0.0]}, {"#dir": "top", "#pose": [0.05, 0.2, 0.0]}]
    answer = client.post(url, json={"x": xs})
    assert answer.status_code == 200
    p = answer.json()["p_feasible"]
    assert len(p) == 2 and all(0.0 <= v <= 1.0 for v in p)
    missing = client.post("/v1/kbs/default/types/" + "0" * 32 + "/predict", json={"x": xs})
    assert missing.status_code == 404
    bad = client.post(url, json={"x": [{"#dir": "up", "#pose": [0.9, 0.2, 0.0]}]})
    assert bad.status_code == 422 and bad.json()["detail"].startswith("x[0].#dir")


def test_a_prior_follows_new_points_while_the_fit_queue_is_busy(sqlite_url: str) -> None:
    """A one-class type answers from its prior; its new points count at the next request even
    while the coordinator is held up (here: held on purpose, as by other knowledge bases' fits)."""
    import threading

    from suggest_support import REACH

    with make_client(sqlite_url, refresh_s=0) as client:
        engine = client.app.state.surrogates
        x = {"#dir": "top", "#pose": [0.3, 0.3, 0.0]}

        def post(pose: list[float]) -> str:
            point = {"graph": REACH, "x": {**x, "#pose": pose}, "feasible": False}
            answer = client.post("/v1/kbs/default/points", json={"points": [point]})
            return answer.json()["results"][0]["type_id"]

        type_id = post([0.9, 0.9, 2.0])
        url = f"/v1/kbs/default/types/{type_id}/predict"
        assert client.app.state.surrogates.wait_idle(timeout=300)
        before = client.post(url, json={"x": [x]}).json()["p_feasible"][0]
        held, release = threading.Event(), threading.Event()
        refresh = engine._refresh

        def busy(key):
            held.set()
            release.wait(timeout=60)
            refresh(key)

        engine._refresh = busy
        try:
            post([0.31, 0.3, 0.0])
            assert held.wait(timeout=120)
            after = client.post(url, json={"x": [x]}).json()["p_feasible"][0]
            state = client.get(f"/v1/kbs/default/types/{type_id}").json()["surrogate"]
        finally:
            release.set()
        assert before > 0.45 and after < 0.2
        assert state["n_fitted"] == 2


def test_predict_refuses_what_a_post_of_the_points_would(app_client: Any) -> None:
    """On both backends: an unknown variable, a missing one, a value out of its domain."""
    from service_support import make_point

    posted = app_client.post("/v1/kbs/default/points", json={"points": [make_point(1)]})
    (result,) = posted.json()["results"]
    url = f"/v1/kbs/default/types/{result['type_id']}/predict"
    good = {"#dir": "top", "#pose": [0.5, 0.5, 0.0]}
    assert app_client.post(url, json={"x": [good]}).status_code == 200
    for bad, named in [
        ({**good, "#yaw": [0.1]}, "x[0].#yaw"),
        ({"#dir": "top"}, "x[0]: missing value for decision '#pose'"),
        ({**good, "#pose": [0.5, 0.5, 9.0]}, "x[0].#pose[2]"),
    ]:
        for body in ({"x": [bad]}, {"x": [good, bad]}):
            answer = app_client.post(url, json=body)
            assert answer.status_code == 422, answer.text
            expected = named if len(body["x"]) == 1 else named.replace("x[0]", "x[1]")
            assert answer.json()["detail"].startswith(expected), answer.json()
            point = make_point(1)
            point["x"] = bad
            stored = app_client.post("/v1/kbs/default/points", json={"points": [point]})
            assert stored.status_code == 422


def test_a_type_loaded_afresh_serves_its_prior_counting_each_point_once(sqlite_url: str) -> None:
    """A service that meets a one-class type for the first time (a restart, another replica)
    serves the stated prior on its stored points, as one that has followed the type serves it:
    the points are in the prior, not weighed in again as points since a fit."""
    from suggest_support import REACH

    from surrogate.encoding import encoder_for
    from surrogate.sources import prior

    x = {"#dir": "top", "#pose": [0.3, 0.3, 0.0]}
    with make_client(sqlite_url) as client:
        posted = client.post(
            "/v1/kbs/default/points",
            json={"points": [{"graph": REACH, "x": x, "feasible": False}]},
        )
        type_id = posted.json()["results"][0]["type_id"]
        space = client.app.state.surrogates.model("default", type_id).space
    z = encoder_for(space).encode_points([x])
    expected = float(prior(z, np.array([False])).proba(z)[0])
    with make_client(sqlite_url, refresh_s=3600) as fresh:
        url = f"/v1/kbs/default/types/{type_id}/predict"
        served = fresh.post(url, json={"x": [x]}).json()["p_feasible"][0]
    assert served == pytest.approx(expected, abs=1e-9) and expected < 0.5

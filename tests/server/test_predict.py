"""POST /v1/kbs/{kb}/types/{type_id}/predict over a real SQLite file and real fits."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from suggest_support import make_client, post_points


@pytest.fixture
def client(sqlite_url: str) -> Iterator[Any]:
    with make_client(sqlite_url) as c:
        yield c


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

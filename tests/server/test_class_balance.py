"""The service's `surrogate.balance_classes` setting reaches the fits planners fetch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from service_support import make_graph
from suggest_support import make_client

from surrogate import snapshot


def _unstructured_type(client: object) -> str:
    """A type of 60 placements, one in ten feasible at random: no region to learn."""
    rng = np.random.default_rng(0)
    body = [
        {
            "graph": make_graph("Balance", ("shelf",)),
            "x": {"#dir": "top", "#pose": [float(rng.random()), float(rng.random()), 0.0]},
            "feasible": bool(rng.random() < 0.1),
        }
        for _ in range(60)
    ]
    answer = client.post("/v1/kbs/default/points", json={"points": body})  # type: ignore[attr-defined]
    assert answer.status_code == 201, answer.text
    return answer.json()["results"][0]["type_id"]


def _served_mean(sqlite_url: str, balance: bool) -> float:
    with make_client(sqlite_url, balance_classes=balance, instant_fit_points=0) as client:
        type_id = _unstructured_type(client)
        assert client.app.state.surrogates.wait_idle(timeout=300)
        answer = client.post("/v1/kbs/default/models", json={"type_ids": [type_id]})
        assert answer.status_code == 200, answer.text
        predictor = snapshot.load(answer.json()["models"][0]["predictor"])
        encoder = client.app.state.surrogates._entries[("default", type_id)].encoder
        rng = np.random.default_rng(1)
        elsewhere = [{"#dir": "top", "#pose": [*rng.random(2), 0.0]} for _ in range(200)]
        return float(predictor.proba(encoder.encode_points(elsewhere)).mean())


@pytest.mark.slow
def test_a_service_that_does_not_balance_serves_its_types_rate_far_from_the_points(
    tmp_path: Path,
) -> None:
    balanced = _served_mean(f"sqlite:///{tmp_path / 'on.db'}", balance=True)
    as_they_are = _served_mean(f"sqlite:///{tmp_path / 'off.db'}", balance=False)
    assert as_they_are < 0.2 and balanced > as_they_are + 0.05

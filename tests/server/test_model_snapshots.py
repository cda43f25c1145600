"""POST /v1/kbs/{kb}/models: each type's predictor as a snapshot, over real fits."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from suggest_support import post_points

from contract.models import ModelSnapshot
from surrogate import snapshot
from surrogate.encoding import SpaceEncoder


@pytest.mark.slow
def test_a_snapshot_answers_what_predict_answers(client: Any) -> None:
    type_ids = post_points(client, 20)
    assert client.app.state.surrogates.wait_idle(timeout=300)
    answer = client.post("/v1/kbs/default/models", json={"type_ids": type_ids})
    assert answer.status_code == 200
    body = answer.json()
    assert {m["type_id"] for m in body["models"]} == set(type_ids)
    assert body["optimizer"]["generations"] >= 0 and body["optimizer"]["mpf_margin_abs"] >= 0
    xs = [{"#dir": d, "#pose": [x, 0.3, 0.0]} for d in ("top", "front") for x in (0.1, 0.9)]
    for raw in body["models"]:
        wire = ModelSnapshot.model_validate(raw)
        assert wire.n_fitted == wire.n_points == 20
        assert wire.predictor["kind"] in {"vgp", "unseen"}
        type_id, model = snapshot.model_from_json(raw)
        encoder = SpaceEncoder(model.space)
        local = model.predictor.proba(encoder.encode_points(xs))
        url = f"/v1/kbs/default/types/{type_id}/predict"
        served = client.post(url, json={"x": xs}).json()["p_feasible"]
        np.testing.assert_allclose(local, served, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_a_known_version_is_left_out_until_a_fit_lands(client: Any) -> None:
    type_ids = post_points(client, 20)
    engine = client.app.state.surrogates
    assert engine.wait_idle(timeout=300)
    first = client.post("/v1/kbs/default/models", json={"type_ids": type_ids}).json()
    known = {m["type_id"]: m["version"] for m in first["models"]}
    again = client.post("/v1/kbs/default/models", json={"type_ids": type_ids, "known": known})
    assert again.status_code == 200 and again.json()["models"] == []
    post_points(client, 10, seed=1)
    assert engine.wait_idle(timeout=300)
    later = client.post("/v1/kbs/default/models", json={"type_ids": type_ids, "known": known})
    assert {m["n_fitted"] for m in later.json()["models"]} == {30}


def test_bad_model_requests_answer_a_clear_4xx(client: Any) -> None:
    type_ids = post_points(client, 4)
    unknown = client.post("/v1/kbs/default/models", json={"type_ids": ["0" * 32]})
    assert unknown.status_code == 404
    assert client.post("/v1/kbs/nope/models", json={"type_ids": type_ids}).status_code == 404
    empty = client.post("/v1/kbs/default/models", json={"type_ids": []})
    assert empty.status_code == 422 and "type_ids" in str(empty.json()["detail"])
    assert client.post("/v1/kbs/default/models", json={"type_id": type_ids}).status_code == 422

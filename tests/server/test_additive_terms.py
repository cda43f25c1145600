"""The service's `surrogate.additive` setting reaches its fits and the snapshots planners fetch."""

from __future__ import annotations

import pytest
from service_support import make_graph
from suggest_support import make_client

from surrogate import snapshot


def _post_placements(client: object, n: int) -> str:
    body = [
        {
            "graph": make_graph("Terms", ("shelf",)),
            "x": {"#dir": ("top", "front")[i % 2], "#pose": [(i * 37 % 97) / 97, 0.5, 0.0]},
            "feasible": i % 2 == 1 and (i * 37 % 97) / 97 > 0.4,
        }
        for i in range(n)
    ]
    answer = client.post("/v1/kbs/default/points", json={"points": body})  # type: ignore[attr-defined]
    assert answer.status_code == 201, answer.text
    return answer.json()["results"][0]["type_id"]


@pytest.mark.slow
@pytest.mark.parametrize(("mode", "terms"), [("none", 0), ("choices", 1), ("decisions", 2)])
def test_the_fit_and_its_snapshot_carry_the_terms_the_setting_asks_for(
    sqlite_url: str, mode: str, terms: int
) -> None:
    with make_client(sqlite_url, additive=mode, instant_fit_points=0) as client:
        type_id = _post_placements(client, 16)
        engine = client.app.state.surrogates
        assert engine.wait_idle(timeout=300)
        assert len(engine._entries[("default", type_id)].fit.predictor.terms) == terms
        answer = client.post("/v1/kbs/default/models", json={"type_ids": [type_id]})
        assert answer.status_code == 200, answer.text
        model = answer.json()["models"][0]
        predictor = snapshot.load(model["predictor"])
        while not hasattr(predictor, "terms"):  # the fit inside its served wrappers
            predictor = predictor.base
        assert len(predictor.terms) == terms


def test_an_unknown_mode_is_refused_at_start(sqlite_url: str) -> None:
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match=r"surrogate\.additive"):
        make_client(sqlite_url, additive="all")

"""CpkbClient.suggest and .predict against `cpkb serve` (uvicorn, fits in a child process):
the session's shared service (`kb_service`), on a fresh knowledge base of this test's own."""

from __future__ import annotations

import time

import pytest
from suggest_support import as_decision, points, suggest_body

from client.client import CpkbClient
from client.errors import BadRequest, NotFound


@pytest.mark.slow
def test_client_suggests_and_predicts_through_the_real_service(live_kb) -> None:
    kb = live_kb.name
    with CpkbClient(live_kb.url, timeout=60) as client:
        results = client.post_points(kb, points(12))
        type_ids = sorted({r.type_id for r in results})
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            states = [client.get_type(kb, t).surrogate for t in type_ids]
            if all(s is not None and s.status == "ready" and s.n_fitted == 12 for s in states):
                break
            time.sleep(0.5)
        else:
            pytest.fail(f"fits did not finish: {states}")
        answer = client.suggest(kb, suggest_body(type_ids, seed=1))
        assert answer.method == "mpf" and set(answer.p_feasible) == set(type_ids)
        p = client.predict(kb, type_ids[0], [as_decision(answer.x)])
        assert len(p) == 1 and 0.0 <= p[0] <= 1.0
        with pytest.raises(NotFound):
            client.predict(kb, "0" * 32, [as_decision(answer.x)])
        with pytest.raises(BadRequest):
            client.suggest(kb, suggest_body(type_ids, fixed={"d": "up"}))

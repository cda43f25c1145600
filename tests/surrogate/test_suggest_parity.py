"""The planner and the service answer a suggest request with the same point from the same model.

Over real requests (recorded from a desk cp-bo run: `fixtures/record_suggest_requests.py`),
answered in order, so that the suggestions each one leaves pending push the next one away in
both places alike. In memory first (the core against the planner's snapshot cache, no server),
then against a real service over HTTP, whose fits the planner fetches as snapshots.
"""

from __future__ import annotations

import json
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from recorded_support import recorded_models

from client import CpkbClient
from client.errors import BadRequest
from contract.models import PointIn, SuggestIn, SuggestOut
from planner.knowledge.local import LocalSurrogates, fetch_from
from surrogate.config import OptimizerConfig
from surrogate.pending import PendingBook
from surrogate.sources import InMemoryModels
from surrogate.suggest import InvalidRequest, SuggestAnswer, SuggestRequest, suggest

RECORDED = json.loads((Path(__file__).parent / "fixtures" / "suggest_requests.json").read_text())
REQUESTS: list[dict[str, Any]] = RECORDED["requests"]
SERVICE_OPTIMIZER = OptimizerConfig(mpf_margin=0.1, mpf_margin_abs=0.025)  # the service's defaults


def _memory() -> InMemoryModels:
    return recorded_models()


def _points(answer: SuggestOut | SuggestAnswer) -> list[Any]:
    return list(answer.batch) or [answer]


def assert_same_answer(a: SuggestOut | SuggestAnswer, b: SuggestOut | SuggestAnswer) -> None:
    """The same points (choices equal, continuous values within 1e-9) and the same MPF and
    P(feasible) of every type, to 1e-9."""
    assert len(_points(a)) == len(_points(b))
    for p, q in zip(_points(a), _points(b), strict=True):
        assert set(p.x) == set(q.x)
        for var, value in p.x.items():
            if isinstance(value, str):
                assert value == q.x[var], var
            else:
                np.testing.assert_allclose(value, q.x[var], rtol=0, atol=1e-9, err_msg=var)
        assert p.mpf == pytest.approx(q.mpf, abs=1e-9)
        assert set(p.p_feasible) == set(q.p_feasible)
        for type_id, value in p.p_feasible.items():
            assert value == pytest.approx(q.p_feasible[type_id], abs=1e-9)
    assert a.n_pending == b.n_pending and a.n_fitted == b.n_fitted


def test_the_recorded_requests_bind_fitted_types_and_ask_for_batches() -> None:
    """The fixture covers what matters: a fitted GP and the stated prior, lookahead, fixed
    variables, excluded siblings, batches."""
    memory = _memory()
    kinds = {type(memory.model(t["type_id"]).predictor).__name__ for t in RECORDED["types"]}
    assert {"UnseenChoices", "PriorPredictor"} <= kinds
    assert any(r.get("lookahead") for r in REQUESTS) and any(r.get("fixed") for r in REQUESTS)
    assert all(r.get("exclude") and r["n"] > 1 for r in REQUESTS)


def test_the_core_and_the_planners_snapshots_answer_alike_in_memory() -> None:
    memory = _memory()
    book = PendingBook(ttl_s=300.0)
    # The service serves the nearest-point stated prior; counting it is the planner's choice.
    local = LocalSurrogates(
        fetch_from(memory, SERVICE_OPTIMIZER, 300.0),
        background=False,
        prior_counts=0.0,
    )
    served = 0
    for recorded in REQUESTS:
        core = suggest(
            memory, SuggestRequest.from_json(recorded), book, key="kb", config=SERVICE_OPTIMIZER
        )
        mine = local.suggest(SuggestIn.model_validate(recorded), rollout=0, stored=0)
        assert mine.method == "mpf-local" and core.method == "mpf"
        assert_same_answer(core, mine)
        served += len(core.batch)
    assert book.count("kb") == local._pending.count("local") == served > len(REQUESTS)


def test_a_seed_gives_one_answer_and_no_seed_a_fresh_one() -> None:
    memory = _memory()
    recorded = next(r for r in REQUESTS if r.get("lookahead"))
    request = SuggestRequest.from_json(recorded)

    def answer(request: SuggestRequest) -> SuggestAnswer:
        return suggest(memory, request, PendingBook(30.0), key="kb", config=SERVICE_OPTIMIZER)

    assert_same_answer(answer(request), answer(request))
    unseeded = SuggestRequest.from_json({**recorded, "seed": None})
    poses = {str(answer(unseeded).batch[1].x["#pose12"]) for _ in range(3)}
    assert len(poses) > 1


def test_the_planners_copy_refuses_what_the_service_refuses() -> None:
    memory = _memory()
    recorded = REQUESTS[0]
    constraint = recorded["constraints"][0]
    wrong = {**recorded, "constraints": [{**constraint, "bind": {"#nope": "#pose12"}}]}
    local = LocalSurrogates(fetch_from(memory, SERVICE_OPTIMIZER), background=False)
    with pytest.raises(InvalidRequest, match=r"constraints\[0\]\.bind\.#nope: not a decision"):
        local.suggest(SuggestIn.model_validate(wrong), rollout=0, stored=0)


@pytest.fixture(scope="module")
def stocked_service(kb_service: str) -> Iterator[tuple[str, str]]:
    """The session's real service, with a fresh knowledge base holding the recorded types'
    points, every fit landed (a fit landing between two answers would change the model under
    a comparison; other knowledge bases' fits on the service do not touch its models)."""
    kb = f"parity-{uuid.uuid4().hex[:8]}"
    with CpkbClient(kb_service) as client:
        client.create_kb(kb)
        points = [
            PointIn(graph=t["graph"], x=p["x"], feasible=p["feasible"], key=f"{i}:{j}")
            for i, t in enumerate(RECORDED["types"])
            for j, p in enumerate(t["points"])
        ]
        stored = client.post_points(kb, points)
        type_ids = {r.type_id for r in stored}
        assert type_ids == {t["type_id"] for t in RECORDED["types"]}
        _wait_for_fits(client, kb, type_ids)
    yield kb_service, kb


def _wait_for_fits(client: CpkbClient, kb: str, type_ids: set[str]) -> None:
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        details = [client.get_type(kb, type_id) for type_id in type_ids]
        if all(
            d.surrogate is not None
            and d.surrogate.n_fitted == d.n_points
            and d.surrogate.status not in ("fitting", "queued")
            for d in details
        ):
            return
        time.sleep(0.2)
    raise AssertionError("the fits did not land in 300 s")


@pytest.mark.slow
def test_the_planner_and_the_service_answer_recorded_requests_alike(stocked_service) -> None:
    url, kb = stocked_service
    with CpkbClient(url) as client:
        local = LocalSurrogates(
            lambda ids, known: client.models(kb, ids, known),
            background=False,
            prior_counts=0.0,
        )
        for recorded in REQUESTS:
            request = SuggestIn.model_validate(recorded)
            served = client.suggest(kb, request)
            mine = local.suggest(request, rollout=0, stored=0)
            assert served.method == "mpf" and mine.method == "mpf-local"
            assert_same_answer(served, mine)


@pytest.mark.slow
def test_the_service_refuses_what_the_planners_copy_refuses(stocked_service) -> None:
    url, kb = stocked_service
    recorded = REQUESTS[0]
    constraint = recorded["constraints"][0]
    wrong = {**recorded, "constraints": [{**constraint, "bind": {"#nope": "#pose12"}}]}
    with CpkbClient(url) as client, pytest.raises(BadRequest, match=r"bind\.#nope: not a decision"):
        client.suggest(kb, SuggestIn.model_validate(wrong))

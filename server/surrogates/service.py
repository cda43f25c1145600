"""Suggest, predict and models: the service's edge of `surrogate.suggest`.

The wire models are read into the surrogate library's own types here and its answers written
back. Every mistake in a request is a 404 (unknown knowledge base or type) or a 422 naming the
field; SpaceExhausted (a finite space wholly excluded) is a 409.
"""

from __future__ import annotations

from contract.models import (
    ModelsIn,
    ModelSnapshot,
    ModelsOut,
    PredictIn,
    PredictOut,
    SuggestIn,
    SuggestOut,
)
from server.errors import Conflict, InvalidInput
from server.graphs import GraphError, check_xs
from server.services.kbs import kb_id
from server.surrogates.engine import SurrogateEngine
from surrogate import snapshot
from surrogate.encoding import EncodingError, encoder_for
from surrogate.optimize import SpaceExhausted
from surrogate.suggest import InvalidRequest, SuggestRequest
from surrogate.suggest import suggest as suggest_point


def suggest(
    engine: SurrogateEngine, kb: str, body: SuggestIn, *, record: bool = True
) -> SuggestOut:
    """The MPF maximiser over `body.space` for the bound constraints (a space-filling point when
    there are none), away from `exclude` and from suggestions still pending; recorded as
    pending itself when `record`."""
    if not body.constraints:
        with engine.store.transaction() as session:
            kb_id(session, kb)
    try:
        answer = suggest_point(
            engine.source(kb),
            SuggestRequest.from_json(body.model_dump()),
            engine.pending,
            key=kb,
            config=engine.config.optimizer,
            record=record,
        )
    except InvalidRequest as exc:
        raise InvalidInput(str(exc)) from exc
    except SpaceExhausted as exc:
        raise Conflict(f"exclude: {exc}") from exc
    return SuggestOut.model_validate(answer.to_json())


def predict(engine: SurrogateEngine, kb: str, type_id: str, body: PredictIn) -> PredictOut:
    """P(feasible) of each x (decision label -> value) under the type's current surrogate."""
    handle = engine.model(kb, type_id)
    try:
        check_xs(body.x, handle.space, where="x")  # as a post of these points would
        encoder = encoder_for(handle.space)
        z = encoder.encode(encoder.columns(body.x, where="x"))
    except (EncodingError, GraphError) as exc:
        raise InvalidInput(str(exc)) from exc
    return PredictOut(p_feasible=[float(p) for p in handle.predictor.proba(z)])


def models(engine: SurrogateEngine, kb: str, body: ModelsIn) -> ModelsOut:
    """The current predictor of each type asked for whose version (its fit: `n_fitted`)
    differs from `known`. The points stored since that fit are in the predictor
    (`RecentPoints`), but do not change the version: a caller weighs in its own new points
    itself, and needs a snapshot again only once a fit has taken them in."""
    changed: list[ModelSnapshot] = []
    for type_id in dict.fromkeys(body.type_ids):
        handle = engine.model(kb, type_id)
        if body.known.get(type_id) == handle.version:
            continue
        changed.append(ModelSnapshot.model_validate(snapshot.model_to_json(type_id, handle)))
    return ModelsOut(
        models=changed,
        optimizer=engine.config.optimizer.model_dump(),
        pending_ttl_s=engine.config.pending_ttl_s,
    )

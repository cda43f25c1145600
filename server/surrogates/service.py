"""Suggest and predict: validate a request against the types' decision spaces, then run MPF.

Every mistake in a request is a 404 (unknown knowledge base or type) or a 422 naming the field;
SpaceExhausted (a finite space wholly excluded) is a 409.
"""

from __future__ import annotations

import dataclasses
import secrets

from client.models import (
    ModelsIn,
    ModelSnapshot,
    ModelsOut,
    PredictIn,
    PredictOut,
    SuggestedPoint,
    SuggestIn,
    SuggestOut,
)
from server.errors import Conflict, InvalidInput
from server.services.kbs import kb_id
from server.surrogates.engine import ModelHandle, SurrogateEngine
from surrogate import snapshot
from surrogate.acquisition import ConstraintTerm
from surrogate.encoding import EncodingError, SpaceEncoder, same_domain, value_column
from surrogate.optimize import SpaceExhausted, space_filling
from surrogate.suggest import mpf_points, served


def _check_binding(i: int, type_id: str, handle: ModelHandle, body: SuggestIn) -> None:
    bind = body.constraints[i].bind
    where = f"constraints[{i}].bind"
    for label in bind:
        if label not in handle.space:
            known = sorted(handle.space)
            raise InvalidInput(f"{where}.{label}: not a decision of type {type_id} ({known})")
    for label, domain in handle.space.items():
        if label not in bind:
            raise InvalidInput(f"{where}: decision {label!r} of type {type_id} is not bound")
        var = bind[label]
        if var in body.space and not same_domain(domain, body.space[var]):
            raise InvalidInput(
                f"space.{var}: domain does not match decision {label!r} of type {type_id} "
                f"({domain.model_dump(exclude={'embedding'})})"
            )
        if var in body.fixed:
            try:
                value_column(f"fixed.{var}", domain, [body.fixed[var]])
            except EncodingError as exc:
                raise InvalidInput(str(exc)) from exc
        elif var not in body.space:
            raise InvalidInput(f"{where}.{label}: variable {var!r} is neither in space nor fixed")


def _check_lookahead(body: SuggestIn) -> None:
    for i, var in enumerate(body.lookahead):
        if var not in body.space:
            raise InvalidInput(f"lookahead[{i}]: {var!r} is not a variable of space")
    if set(body.space) <= set(body.lookahead):
        raise InvalidInput("lookahead: leaves no variable of space to suggest")


def suggest(engine: SurrogateEngine, kb: str, body: SuggestIn) -> SuggestOut:
    """The MPF maximiser over `body.space` for the bound constraints (a space-filling point when
    there are none), away from `exclude` and from suggestions still pending."""
    _check_lookahead(body)
    terms: list[ConstraintTerm] = []
    fitted: dict[str, int] = {}
    for i, constraint in enumerate(body.constraints):
        handle = engine.model(kb, constraint.type_id)
        _check_binding(i, constraint.type_id, handle, body)
        terms.append(
            ConstraintTerm.build(
                constraint.type_id, handle.predictor, handle.space, constraint.bind, body.fixed
            )
        )
        fitted[constraint.type_id] = handle.n_fitted
    if not terms:
        with engine.store.transaction() as session:
            kb_id(session, kb)
    type_ids = frozenset(fitted)
    pending = engine.pending.for_request(kb, type_ids)
    seed = body.seed if body.seed is not None else secrets.randbits(31)
    try:
        if terms:
            points = mpf_points(
                terms, body, pending=pending, seed=seed, config=engine.config.optimizer
            )
        else:
            x = space_filling(
                body.space, fixed=body.fixed, exclude=body.exclude, pending=pending, seed=seed
            )
            points = [SuggestedPoint(x=x, mpf=0.5, p_feasible={})]
    except EncodingError as exc:
        raise InvalidInput(str(exc)) from exc
    except SpaceExhausted as exc:
        raise Conflict(f"exclude: {exc}") from exc
    return served(
        body,
        points,
        engine.pending,
        kb,
        method="mpf" if terms else "space-filling",
        n_fitted=fitted,
        n_pending=len(pending),
    )


def predict(engine: SurrogateEngine, kb: str, type_id: str, body: PredictIn) -> PredictOut:
    """P(feasible) of each x (decision label -> value) under the type's current surrogate."""
    handle = engine.model(kb, type_id)
    try:
        encoder = SpaceEncoder(handle.space)
        z = encoder.encode(encoder.columns(body.x, where="x"))
    except EncodingError as exc:
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
        version = str(handle.n_fitted)
        if body.known.get(type_id) == version:
            continue
        changed.append(
            ModelSnapshot(
                type_id=type_id,
                version=version,
                space=handle.space,
                n_points=handle.n_points,
                n_fitted=handle.n_fitted,
                predictor=snapshot.dump(handle.predictor),
            )
        )
    return ModelsOut(
        models=changed,
        optimizer=dataclasses.asdict(engine.config.optimizer),
        pending_ttl_s=engine.config.pending_ttl_s,
    )

"""MPF suggestions and per-type feasibility predictions (thin: see server.surrogates.service)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Request

from client.models import (
    ModelsIn,
    ModelsOut,
    PredictIn,
    PredictOut,
    SuggestIn,
    SuggestOut,
)
from server.api.responses import BODY, IN_KB, errors
from server.errors import Unavailable
from server.surrogates import service
from server.surrogates.engine import SurrogateEngine

router = APIRouter(prefix="/v1/kbs/{kb}", tags=["surrogates"], responses=IN_KB)


def _engine(request: Request) -> SurrogateEngine:
    engine = request.app.state.surrogates
    if engine is None:
        raise Unavailable("surrogates are disabled in this service (CPKB_SURROGATE_ENABLED=false)")
    return engine


EngineDep = Annotated[SurrogateEngine, Depends(_engine)]


@router.post("/suggest", responses=errors(409) | BODY)
def suggest(kb: str, body: SuggestIn, engine: EngineDep) -> SuggestOut:
    """The point of `space` maximising min_i P(constraint i feasible), fixed variables applied,
    never an excluded point, away from suggestions still pending."""
    return service.suggest(engine, kb, body)


@router.post("/models", responses=BODY)
def models(kb: str, body: ModelsIn, engine: EngineDep) -> ModelsOut:
    """Each type's current predictor, for MPF in the caller's own process; types whose
    version the caller already holds (`known`) are left out."""
    return service.models(engine, kb, body)


@router.post("/types/{type_id}/predict", responses=BODY)
def predict(kb: str, type_id: str, body: PredictIn, engine: EngineDep) -> PredictOut:
    """P(feasible) of each x under the type's current surrogate."""
    return service.predict(engine, kb, type_id, body)

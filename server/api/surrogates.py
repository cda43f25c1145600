"""MPF suggestions and per-type feasibility predictions (thin: see server.surrogates.service)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Request

from contract.models import (
    ModelsIn,
    ModelsOut,
    PredictIn,
    PredictOut,
    SuggestIn,
    SuggestOut,
)
from server.api.deps import WriterDep, in_heavy_lane
from server.api.responses import BODY, IN_KB, errors
from server.errors import Unavailable
from server.surrogates import service
from server.surrogates.engine import SurrogateEngine

router = APIRouter(prefix="/v1/kbs/{kb}", tags=["surrogates"], responses=IN_KB)


def _engine(request: Request) -> SurrogateEngine:
    engine = request.app.state.surrogates
    if engine is None:
        raise Unavailable("surrogates are disabled in this service (CPKB_SURROGATE__ENABLED=false)")
    return engine


EngineDep = Annotated[SurrogateEngine, Depends(_engine)]


@router.post("/suggest", responses=errors(409) | BODY)
async def suggest(
    kb: str, body: SuggestIn, engine: EngineDep, writer: WriterDep, request: Request
) -> SuggestOut:
    """The point of `space` maximising min_i P(constraint i feasible), fixed variables applied,
    never an excluded point, away from suggestions still pending. The answer is recorded as
    pending only for a caller that may write (a valid token, where the service has one)."""
    return await in_heavy_lane(request, service.suggest, engine, kb, body, record=writer)


@router.post("/models", responses=BODY)
def models(kb: str, body: ModelsIn, engine: EngineDep) -> ModelsOut:
    """Each type's current predictor, for MPF in the caller's own process; types whose
    version the caller already holds (`known`) are left out."""
    return service.models(engine, kb, body)


@router.post("/types/{type_id}/predict", responses=BODY)
async def predict(
    kb: str, type_id: str, body: PredictIn, engine: EngineDep, request: Request
) -> PredictOut:
    """P(feasible) of each x under the type's current surrogate."""
    return await in_heavy_lane(request, service.predict, engine, kb, type_id, body)

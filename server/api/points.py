"""Posting points and reading a type's table (paged JSON or CSV)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status
from fastapi.responses import StreamingResponse

from contract.models import (
    PointsIn,
    PointsOut,
    PointsPage,
    PointsSinceIn,
    PointsSinceOut,
)
from server.api.deps import HooksDep, SettingsDep, StoreDep
from server.api.responses import BODY, IN_KB, INVALID, errors, json_errors
from server.observability import record_planner_suggests, record_points_ingested
from server.services import points


class CsvResponse(StreamingResponse):
    media_type = "text/csv"


router = APIRouter(prefix="/v1/kbs/{kb}", tags=["points"], responses=IN_KB)


@router.post("/points", status_code=status.HTTP_201_CREATED, responses=errors(409) | BODY)
def post_points(
    kb: str, body: PointsIn, store: StoreDep, hooks: HooksDep, settings: SettingsDep
) -> PointsOut:
    """Store up to 1000 points in one transaction; a repeated `key` stores nothing twice.
    413 when their distinct graphs hold more than CPKB_MAX_REQUEST_GRAPH_NODES nodes in all."""
    max_nodes = settings.max_request_graph_nodes
    outcome = points.add_points(store, kb, body.points, max_nodes=max_nodes)
    if outcome.n_new:
        record_points_ingested(kb, outcome.n_new, outcome.n_new_types)
        record_planner_suggests(p.source.model_extra if p.source else None for p in body.points)
        hooks.notify_points_added(kb, outcome.touched)
    return PointsOut(results=outcome.results)


@router.post("/points/since", responses=BODY)
def points_since(kb: str, body: PointsSinceIn, store: StoreDep) -> PointsSinceOut:
    """Other writers' points of the watched types stored after a cursor (live sharing)."""
    return points.points_since(store, kb, body)


@router.get("/types/{type_id}/points", responses=INVALID)
def list_points(
    kb: str,
    type_id: str,
    store: StoreDep,
    settings: SettingsDep,
    limit: Annotated[int | None, Query(ge=1)] = None,
    cursor: Annotated[str | None, Query(max_length=32)] = None,
) -> PointsPage:
    """A page of the type's points in insertion order; pass `next_cursor` back for the next."""
    size = min(limit or settings.default_page_size, settings.max_page_size)
    return points.list_points(store, kb, type_id, limit=size, cursor=cursor)


@router.get(
    "/types/{type_id}/points.csv",
    response_class=CsvResponse,
    responses=json_errors(401, 404, 422, 503)
    | {
        200: {
            "description": "The type's points, a row each: a column per decision value, "
            "provenance columns after.",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        }
    },
)
def export_points_csv(kb: str, type_id: str, store: StoreDep) -> CsvResponse:
    """The type's table as CSV: one column per decision value, provenance columns after."""
    lines = points.iter_csv(store, kb, type_id)
    return CsvResponse(
        lines,
        headers={"Content-Disposition": f'attachment; filename="{kb}-{type_id}.csv"'},
    )

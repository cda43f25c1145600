"""Posting points and reading a type's table (paged JSON or CSV)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status
from fastapi.responses import StreamingResponse

from client.models import PointsIn, PointsOut, PointsPage, PointsSinceIn, PointsSinceOut
from server.api.deps import HooksDep, SettingsDep, StoreDep
from server.observability import record_planner_suggests, record_points_ingested
from server.services import points

router = APIRouter(prefix="/v1/kbs/{kb}", tags=["points"])


@router.post("/points", status_code=status.HTTP_201_CREATED)
def post_points(kb: str, body: PointsIn, store: StoreDep, hooks: HooksDep) -> PointsOut:
    """Store up to 1000 points in one transaction; a repeated `key` stores nothing twice."""
    outcome = points.add_points(store, kb, body.points)
    if outcome.n_new:
        record_points_ingested(kb, outcome.n_new, outcome.n_new_types)
        record_planner_suggests(p.source.model_extra if p.source else None for p in body.points)
        hooks.notify_points_added(kb, outcome.touched)
    return PointsOut(results=outcome.results)


@router.post("/points/since")
def points_since(kb: str, body: PointsSinceIn, store: StoreDep) -> PointsSinceOut:
    """Other writers' points of the watched types stored after a cursor (live sharing)."""
    return points.points_since(store, kb, body)


@router.get("/types/{type_id}/points")
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


@router.get("/types/{type_id}/points.csv", response_class=StreamingResponse)
def export_points_csv(kb: str, type_id: str, store: StoreDep) -> StreamingResponse:
    """The type's table as CSV: one column per decision value, provenance columns after."""
    lines = points.iter_csv(store, kb, type_id)
    return StreamingResponse(
        lines,
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{kb}-{type_id}.csv"'},
    )

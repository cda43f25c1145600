"""Posting points and reading a type's table (paged JSON or CSV)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated

from fastapi import APIRouter, Depends, Query, status
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
from server.errors import InvalidInput
from server.observability import record_planner_suggests, record_points_ingested
from server.services import csv_tables, points


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


Name = Annotated[str | None, Query(max_length=128)]


def _utc(moment: datetime | None) -> datetime | None:
    """A time without a zone is taken as UTC, the zone every point's `created_at` is in."""
    if moment is None or moment.tzinfo is not None:
        return moment
    return moment.replace(tzinfo=UTC)


def point_filter(
    feasible: Annotated[bool | None, Query(description="only this label")] = None,
    task: Annotated[Name, Query(description="only this task's points (source.task)")] = None,
    run: Annotated[Name, Query(description="only this run's points (source.run)")] = None,
    worker: Annotated[Name, Query(description="only this worker's points (source.worker)")] = None,
    since: Annotated[datetime | None, Query(description="stored at or after (ISO 8601)")] = None,
    until: Annotated[datetime | None, Query(description="stored before (ISO 8601)")] = None,
) -> points.PointFilter:
    """The filters of a points listing; a time without a zone is UTC."""
    since, until = _utc(since), _utc(until)
    if since is not None and until is not None and since >= until:
        raise InvalidInput("since must be before until")
    return points.PointFilter(feasible, task, run, worker, since, until)


Filter = Annotated[points.PointFilter, Depends(point_filter)]


@router.get("/types/{type_id}/points", responses=INVALID)
def list_points(
    kb: str,
    type_id: str,
    store: StoreDep,
    settings: SettingsDep,
    where: Filter,
    limit: Annotated[int | None, Query(ge=1)] = None,
    cursor: Annotated[str | None, Query(max_length=32)] = None,
) -> PointsPage:
    """A page of the type's points in insertion order, filtered by label, provenance and
    storage time; pass `next_cursor` back (with the same filters) for the next."""
    size = min(limit or settings.default_page_size, settings.max_page_size)
    return points.list_points(store, kb, type_id, limit=size, cursor=cursor, where=where)


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
def export_points_csv(kb: str, type_id: str, store: StoreDep, where: Filter) -> CsvResponse:
    """The type's table as CSV: one column per decision value, provenance columns after;
    the filters as for the listing. Text cells that start like a formula begin with `'`."""
    lines = csv_tables.iter_csv(store, kb, type_id, where=where)
    return CsvResponse(
        lines,
        headers={"Content-Disposition": f'attachment; filename="{kb}-{type_id}.csv"'},
    )


@router.get(
    "/points.csv",
    response_class=CsvResponse,
    responses=json_errors(401, 404, 422, 503)
    | {
        200: {
            "description": "Every point of the knowledge base, a row each: its type's id and "
            "failure, its decision values as one JSON object, provenance columns after.",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        }
    },
)
def export_kb_csv(kb: str, store: StoreDep, where: Filter) -> CsvResponse:
    """The whole knowledge base as one CSV (beside the dashboard's zip of a CSV per type);
    the filters as for a type's listing."""
    return CsvResponse(
        csv_tables.iter_kb_csv(store, kb, where=where),
        headers={"Content-Disposition": f'attachment; filename="{kb}-points.csv"'},
    )

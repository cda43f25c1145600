"""The dashboard's routes: HTML pages at `/` and `/ui/...`, the JSON they poll, and SVG images.

Thin: data comes from `server.dashboard.views` (service functions), pictures from the SVG
renderers; the pages re-render their changing parts server-side and the script swaps them in.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response, StreamingResponse
from fastapi.templating import Jinja2Templates
from markupsafe import Markup

from server.dashboard import figures, views
from server.dashboard.export import export_stream
from server.dashboard.graph_svg import render_svg
from server.errors import InvalidInput, NotFound
from server.services import types

HERE = Path(__file__).parent
STATIC = {
    "dashboard.js": "text/javascript",
    "dashboard.css": "text/css",
}
SVG = "image/svg+xml"

templates = Jinja2Templates(directory=HERE / "templates")
router = APIRouter(include_in_schema=False)

DimName = Annotated[str | None, Query(max_length=200)]
GridSize = Annotated[int, Query(ge=4, le=40)]
# Panels a row: the page asks for as many as its width holds, so that a phone stacks them.
Cols = Annotated[int | None, Query(ge=1, le=12)]
KbName = Annotated[str | None, Query(max_length=64)]
PointId = Annotated[int | None, Query(ge=0, le=2**63 - 1)]


def table_query(
    feasible: Annotated[Literal["", "true", "false"], Query(description="'' for both labels")] = "",
    task: Annotated[str, Query(max_length=128, description="'' for every task")] = "",
    run: Annotated[str, Query(max_length=128, description="'' for every run")] = "",
    order: Literal["newest", "oldest"] = "newest",
    after: PointId = None,
    before: PointId = None,
    limit: Annotated[int, Query(ge=1, le=500)] = views.POINTS_PER_PAGE,
    x: DimName = None,
    y: DimName = None,
    hold: Annotated[PointId, Query(description="the point the pictures go through")] = None,
) -> views.TableQuery:
    """The points table's query string: unknown values are a 422, never silently ignored."""
    if after is not None and before is not None:
        raise InvalidInput("give after= or before=, not both")
    return views.TableQuery(
        feasible=None if feasible == "" else feasible == "true",
        task=task or None,
        run=run or None,
        newest_first=order == "newest",
        after=after,
        before=before,
        limit=limit,
        axes=(x, y),
        hold=hold,
    )


Table = Annotated[views.TableQuery, Depends(table_query)]


def _fmt_value(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.3g}" for v in value) + "]"
    return str(value)


def _fmt_ratio(value: float | None) -> str:
    return "" if value is None else f"{100 * value:.0f}%"


templates.env.filters["value"] = _fmt_value
templates.env.filters["ratio"] = _fmt_ratio


def _fragments(name: str, **context: Any) -> dict[str, str]:
    """Render every macro of `templates/name` whose name ends in `_rows` or `_panel`, keyed by
    the element id it fills (the macro name with `_` as `-`)."""
    module = templates.env.get_template(name).make_module(context)
    return {
        macro.replace("_", "-"): str(getattr(module, macro)())
        for macro in dir(module)
        if macro.endswith(("_rows", "_panel"))
    }


def _state(request: Request) -> tuple[Any, Any]:
    return request.app.state.store, request.app.state.hooks


Offset = Annotated[int, Query(ge=0, le=10**9)]
TypesLimit = Annotated[int, Query(ge=1, le=500)]


@router.get("/", response_class=HTMLResponse)
def index(
    request: Request,
    kb: KbName = None,
    offset: Offset = 0,
    limit: TypesLimit = views.TYPES_PER_PAGE,
) -> Response:
    store, _ = _state(request)
    data = views.overview(store, kb, offset=offset, limit=limit)
    history = ""
    if data["kb"] is not None:
        history = Markup(figures.kb_history(store, data["kb"]))
    context = {**data, "history_svg": history, "fragments": _fragments("_overview.html", **data)}
    return templates.TemplateResponse(request, "index.html", context)


@router.get("/ui/api/overview")
def overview_json(
    request: Request,
    kb: KbName = None,
    offset: Offset = 0,
    limit: TypesLimit = views.TYPES_PER_PAGE,
) -> JSONResponse:
    store, _ = _state(request)
    data = views.overview(store, kb, offset=offset, limit=limit)
    return JSONResponse({**data, "fragments": _fragments("_overview.html", **data)})


@router.get("/ui/kbs/{kb}/types/{type_id}", response_class=HTMLResponse)
def type_page(
    request: Request,
    kb: str,
    type_id: str,
    table: Table,
) -> Response:
    store, hooks = _state(request)
    data = views.type_page(store, hooks, kb, type_id, table=table)
    # Both SVGs are ours, every text in them escaped by the renderers.
    graph = Markup(render_svg(data["detail"].graph))
    inputs = _inputs(request, kb, type_id, table.hold)
    heatmap = Markup(figures.heatmap(inputs, data["x_dim"], data["y_dim"], 20))
    slices = Markup(figures.slices(inputs))
    parallel = Markup(figures.parallel(inputs))
    history = Markup(figures.type_history(store, kb, type_id))
    context = {
        **data,
        "graph_svg": graph,
        "heatmap_svg": heatmap,
        "slices_svg": slices,
        "parallel_svg": parallel,
        "history_svg": history,
        "held": inputs.held,
        "figure_key": _figure_key(data),
        "fragments": _fragments("_type.html", **data),
    }
    return templates.TemplateResponse(request, "type.html", context)


@router.get("/ui/api/kbs/{kb}/types/{type_id}")
def type_json(request: Request, kb: str, type_id: str, table: Table) -> JSONResponse:
    store, hooks = _state(request)
    data = views.type_status(store, hooks, kb, type_id, table)
    fragments = _fragments("_type.html", **data)
    data["table"] = {k: v for k, v in data["table"].items() if k != "query"}
    return JSONResponse({**data, "figure_key": _figure_key(data), "fragments": fragments})


@router.get("/ui/compare", response_class=HTMLResponse)
def compare_page(
    request: Request,
    a: Annotated[str, Query(max_length=64, description="the first knowledge base")],
    b: Annotated[str, Query(max_length=64, description="the second knowledge base")],
) -> Response:
    """Two knowledge bases' types side by side."""
    store, _ = _state(request)
    return templates.TemplateResponse(request, "compare.html", views.compare(store, a, b))


@router.get("/ui/kbs/{kb}/points/{point_id}", response_class=HTMLResponse)
def point_page(request: Request, kb: str, point_id: int) -> Response:
    """A page per point: its values and provenance, the model's verdict at it, and a link to
    its type's pictures drawn through it."""
    store, hooks = _state(request)
    state = request.app.state
    judge = getattr(state, "predict_with_uncertainty", None)
    data = views.point_page(store, hooks, kb, point_id, judge)
    return templates.TemplateResponse(request, "point.html", data)


@router.get("/ui/kbs/{kb}/types/{type_id}/graph.svg")
def graph_svg(request: Request, kb: str, type_id: str) -> Response:
    store, _ = _state(request)
    return Response(render_svg(types.get_type(store, kb, type_id).graph), media_type=SVG)


@router.get("/ui/kbs/{kb}/types/{type_id}/heatmap.svg")
def heatmap_svg(
    request: Request,
    kb: str,
    type_id: str,
    x: DimName = None,
    y: DimName = None,
    n: GridSize = 20,
    hold: PointId = None,
    cols: Cols = None,
) -> Response:
    inputs = _inputs(request, kb, type_id, hold)
    return Response(figures.heatmap(inputs, x, y, n, cols), media_type=SVG)


@router.get("/ui/kbs/{kb}/types/{type_id}/slices.svg")
def slices_svg(
    request: Request, kb: str, type_id: str, hold: PointId = None, cols: Cols = None
) -> Response:
    return Response(figures.slices(_inputs(request, kb, type_id, hold), cols), media_type=SVG)


@router.get("/ui/kbs/{kb}/types/{type_id}/parallel.svg")
def parallel_svg(request: Request, kb: str, type_id: str, cols: Cols = None) -> Response:
    """Parallel coordinates of the type's points; `cols`: the axes the page's width holds."""
    return Response(figures.parallel(_inputs(request, kb, type_id), cols), media_type=SVG)


HistoryAxis = Annotated[
    Literal["time", "point", "run"],
    Query(description="time (idle pauses left out), point (storage order) or run"),
]


@router.get("/ui/kbs/{kb}/types/{type_id}/history.svg")
def type_history_svg(
    request: Request, kb: str, type_id: str, axis: HistoryAxis = "time", cols: Cols = None
) -> Response:
    store, _ = _state(request)
    svg = figures.type_history(store, kb, type_id, axis, cols or 2)
    return Response(svg, media_type=SVG)


@router.get("/ui/kbs/{kb}/history.svg")
def kb_history_svg(
    request: Request, kb: str, axis: HistoryAxis = "time", cols: Cols = None
) -> Response:
    store, _ = _state(request)
    return Response(figures.kb_history(store, kb, axis, cols or 2), media_type=SVG)


@router.get("/ui/kbs/{kb}/export.zip")
def export_zip(request: Request, kb: str) -> Response:
    """The whole knowledge base: types.json and one CSV per type (see server.dashboard.export)."""
    store, hooks = _state(request)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return StreamingResponse(
        export_stream(store, hooks, kb),
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="cpkb-{kb}-{stamp}.zip"'},
    )


@router.get("/ui/static/{name}")
def static(name: str) -> Response:
    if name not in STATIC:
        raise NotFound(f"no static file {name!r}")
    return Response(
        (HERE / "static" / name).read_bytes(),
        media_type=STATIC[name],
        headers={"Cache-Control": "max-age=60"},
    )


def _inputs(request: Request, kb: str, type_id: str, hold: int | None = None) -> figures.Inputs:
    store, hooks = _state(request)
    state = request.app.state
    predict = getattr(state, "predict", None)
    judge = getattr(state, "predict_with_uncertainty", None) if predict is not None else None
    return figures.inputs(store, hooks, predict, kb, type_id, judge, hold)


def _figure_key(data: dict[str, Any]) -> str:
    """Changes whenever the type's pictures would: new points or a new surrogate version."""
    surrogate = data.get("surrogate") or {}
    return f"{data['n_points']}:{surrogate.get('version')}"

"""What the dashboard shows, assembled from the service functions (no SQL here).

Each view is a plain dict handed to a Jinja2 template; the same dicts, minus the rendered
fragments, are the JSON that the page's script polls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from typing import Any
from urllib.parse import quote, urlencode

from contract.models import SurrogateState, TypeDetail, TypeSummary
from server.dashboard.heatmap import Dim, continuous_dims
from server.db import Store
from server.hooks import ServiceHooks
from server.services import activity, browse, kbs, types
from server.services.points import PointFilter
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder

# (kb, type_id, decision values) -> P(feasible) per value, or None when no surrogate answers.
Predictor = Callable[[str, str, list[dict[str, Any]]], list[float] | None]
MAX_OVERLAY_POINTS = 2000
TYPES_PER_PAGE = 50
POINTS_PER_PAGE = 50


def ago(moment: datetime | None, now: datetime | None = None) -> str:
    """`12 s ago`, `5 min ago`, `3 h ago`, `2 d ago`; an empty string for no time."""
    if moment is None:
        return ""
    seconds = max(0.0, ((now or datetime.now(UTC)) - moment).total_seconds())
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{int(seconds // size)} {unit} ago"
    return f"{int(seconds)} s ago"


def feasible_ratio(summary: TypeSummary) -> float | None:
    if summary.n_points == 0:
        return None
    return (summary.n_points - summary.n_infeasible) / summary.n_points


def pick_kb(store: Store, requested: str | None) -> tuple[list[Any], str | None]:
    """All knowledge bases, and the one to show: the requested, else the one updated last
    (where the data a user wants to see is), else `default`, else the first."""
    bases = kbs.list_kbs(store)
    names = [b.name for b in bases]
    if requested is not None:
        return bases, requested
    recent = browse.most_recent_kb(store)
    if recent is not None:
        return bases, recent
    if kbs.DEFAULT_KB in names:
        return bases, kbs.DEFAULT_KB
    return bases, names[0] if names else None


def overview(
    store: Store, kb: str | None, *, offset: int = 0, limit: int = TYPES_PER_PAGE
) -> dict[str, Any]:
    """The knowledge bases, a page of the chosen one's types with provenance (a fixed number
    of queries however many types there are), and the recent workers."""
    bases, chosen = pick_kb(store, kb)
    type_rows = []
    total = 0
    if chosen is not None:
        page = browse.types_page(store, chosen, offset=offset, limit=limit)
        total = page.total
        for row in page.rows:
            type_rows.append(
                {
                    **row.summary.model_dump(mode="json"),
                    "feasible_ratio": feasible_ratio(row.summary),
                    "updated_ago": ago(row.summary.updated_at),
                    "tasks": [{"name": name, "n_points": n} for name, n in row.tasks],
                    "n_tasks": row.n_tasks,
                    "n_runs": row.n_runs,
                }
            )
    workers = [
        {**asdict(w), "last_seen": w.last_seen.isoformat(), "last_seen_ago": ago(w.last_seen)}
        for w in activity.recent_workers(store, limit=20)
    ]

    where = {"kb": chosen} if chosen else {}

    def href(at: int) -> str:
        return "/?" + urlencode({**where, "offset": at, "limit": limit})

    return {
        "kb": chosen,
        "kbs": [b.model_dump(mode="json") for b in bases],
        "types": type_rows,
        "types_total": total,
        "types_pager": {
            "first": offset + 1 if type_rows else 0,
            "last": offset + len(type_rows),
            "prev_href": href(max(0, offset - limit)) if offset > 0 else None,
            "next_href": href(offset + limit) if offset + limit < total else None,
        },
        "poll": "/ui/api/overview?" + urlencode({**where, "offset": offset, "limit": limit}),
        "workers": workers,
        # Changes whenever the history would: a point more in the chosen base.
        "figure_key": str(sum(b.n_points for b in bases if b.name == chosen)),
        "generated_at": datetime.now(UTC).isoformat(),
    }


def surrogate_state(hooks: ServiceHooks, kb: str, type_id: str) -> dict[str, Any] | None:
    state: SurrogateState | None = hooks.surrogate(kb, type_id)
    return None if state is None else state.model_dump(mode="json")


@dataclass(frozen=True)
class TableQuery:
    """What the points table shows: filters, order and the page (`after` / `before` a point id,
    in display order), and the heat map's axes to keep in its links."""

    feasible: bool | None = None
    task: str | None = None
    run: str | None = None
    newest_first: bool = True
    after: int | None = None
    before: int | None = None
    limit: int = POINTS_PER_PAGE
    axes: tuple[str | None, str | None] = (None, None)
    hold: int | None = None  # the point the pictures are drawn through (None: newest feasible)

    def params(self, **page: int) -> dict[str, str | int]:
        """The query string of this view with another page (`after=` or `before=`)."""
        out: dict[str, str | int] = {}
        if self.feasible is not None:
            out["feasible"] = "true" if self.feasible else "false"
        if self.task is not None:
            out["task"] = self.task
        if self.run is not None:
            out["run"] = self.run
        out["order"] = "newest" if self.newest_first else "oldest"
        out["limit"] = self.limit
        for name, value in zip(("x", "y"), self.axes, strict=True):
            if value is not None:
                out[name] = value
        if self.hold is not None:
            out["hold"] = self.hold
        return {**out, **page}

    def href(self, **page: int) -> str:
        return "?" + urlencode(self.params(**page))

    def holding(self, point_id: int | None) -> str:
        """This view (its first page) drawn through another point; None: the default one."""
        params = {k: v for k, v in self.params().items() if k != "hold"}
        if point_id is not None:
            params["hold"] = point_id
        return "?" + urlencode(params)


def points_table(store: Store, kb: str, type_id: str, query: TableQuery) -> dict[str, Any]:
    view = browse.browse_points(
        store,
        kb,
        type_id,
        limit=query.limit,
        after=query.after,
        before=query.before,
        newest_first=query.newest_first,
        where=PointFilter(query.feasible, query.task, query.run),
    )
    paged = query.after is not None or query.before is not None
    return {
        "points": [p.model_dump(mode="json") for p in view.points],
        "n_matching": view.n_matching,
        "next_href": query.href(after=view.after) if view.after is not None else None,
        "prev_href": query.href(before=view.before) if view.before is not None else None,
        "first_href": query.href() if paged else None,
        "query": query,
    }


def type_status(
    store: Store, hooks: ServiceHooks, kb: str, type_id: str, table: TableQuery | None = None
) -> dict[str, Any]:
    """The parts of a type page that change while points arrive: counts, provenance, surrogate,
    the points table as filtered and paged."""
    detail: TypeDetail = types.get_type(store, kb, type_id)
    table = table or TableQuery()
    shown = points_table(store, kb, type_id, table)
    surrogate = surrogate_state(hooks, kb, type_id)
    lengthscales = (surrogate or {}).get("lengthscales")
    relevance = dim_lengthscales(detail.space, lengthscales)
    dims = continuous_dims(detail.space)
    dx, dy = choose_dims(dims, *table.axes, relevance)
    columns, mismatch = fit_columns(detail.space, lengthscales)
    accuracy = (surrogate or {}).get("train_accuracy")
    # A page at the start polls as the first page, so that new points join it.
    page = _page(table) if shown["prev_href"] else {}
    held_id = table.hold
    if held_id is None:
        newest = browse.browse_points(
            store, kb, type_id, limit=1, newest_first=True, where=PointFilter(feasible=True)
        ).points
        if not newest:  # no feasible point: the pictures go through the newest one
            newest = browse.browse_points(store, kb, type_id, limit=1, newest_first=True).points
        held_id = newest[0].point_id if newest else None
    return {
        "kb": kb,
        "type_id": type_id,
        "by_task": [
            {
                **asdict(share),
                "first": share.first.isoformat(),
                "last": share.last.isoformat(),
                "ratio": share.n_feasible / share.n,
                "last_ago": ago(share.last),
            }
            for share in browse.per_task(store, kb, type_id)
        ],
        "n_points": detail.n_points,
        "n_infeasible": detail.n_infeasible,
        "feasible_ratio": feasible_ratio(detail),
        "updated_at": detail.updated_at.isoformat() if detail.updated_at else None,
        "updated_ago": ago(detail.updated_at),
        "provenance": asdict(activity.type_provenance(store, kb, type_id)),
        "surrogate": surrogate,
        "dims": [d.name for d in dims],
        "x_dim": dx.name if dx else None,
        "y_dim": dy.name if dy else None,
        "axes_chosen": any(a is not None for a in table.axes),
        "columns": columns,
        "columns_mismatch": mismatch,
        "train_accuracy": accuracy,
        "space": {label: dom.model_dump(mode="json") for label, dom in detail.space.items()},
        "table": shown,
        "held_id": held_id,
        "poll": f"/ui/api/kbs/{quote(kb, safe='')}/types/{type_id}" + table.href(**page),
    }


def _page(table: TableQuery) -> dict[str, int]:
    if table.after is not None:
        return {"after": table.after}
    return {"before": table.before} if table.before is not None else {}


def dim_lengthscales(space: dict[str, Any], lengthscales: list[float] | None) -> dict[str, float]:
    """The fitted lengthscale of each continuous dimension (`#pose[1]` -> 0.3), read from the
    encoder's columns (a heading on a circle: the shorter of its two); empty without a fit or
    when the fit's columns do not match."""
    if not lengthscales:
        return {}
    encoder = SpaceEncoder(space_from_json({k: d.model_dump() for k, d in space.items()}))
    if len(lengthscales) != encoder.dim:
        return {}
    out = {}
    for var in encoder.vars:
        if var.table is not None or not var.in_z:
            continue
        for i in range(var.width):
            columns = [var.start + i]
            if i == var.circle:  # the heading's cosine column and its sine column, last
                columns.append(var.start + var.width)
            out[f"{var.name}[{i}]"] = float(min(lengthscales[c] for c in columns))
    return out


def choose_dims(
    dims: list[Dim], x: str | None, y: str | None, relevance: dict[str, float] | None = None
) -> tuple[Dim | None, Dim | None]:
    """The heat map's axes by name (`#pose[0]`); missing or unknown names fall back to the
    dimensions the fit finds most relevant (shortest lengthscale first), else the first two."""
    relevance = relevance or {}
    dims = sorted(dims, key=lambda d: relevance.get(d.name, math.inf))
    by_name = {d.name: d for d in dims}
    dx = by_name.get(x or "") or (dims[0] if dims else None)
    rest = [d for d in dims if d != dx]
    dy = by_name.get(y or "") if y != (dx.name if dx else None) else None
    return dx, dy or (rest[0] if rest else None)


def type_page(
    store: Store, hooks: ServiceHooks, kb: str, type_id: str, *, table: TableQuery
) -> dict[str, Any]:
    return {
        **type_status(store, hooks, kb, type_id, table),
        "detail": types.get_type(store, kb, type_id),
    }


def fit_columns(
    space: dict[str, Any], lengthscales: list[float] | None
) -> tuple[list[tuple[str, float]], str | None]:
    """Every lengthscale of the fit named by its column of the encoding (choices and
    separations included), shortest first; and why they cannot be named, if so."""
    if not lengthscales:
        return [], None
    encoder = SpaceEncoder(space_from_json({k: d.model_dump() for k, d in space.items()}))
    names = encoder.column_names()
    if len(names) != len(lengthscales):
        return [], (
            f"the fit has {len(lengthscales)} lengthscales and this type's encoding "
            f"{len(names)} columns, so they cannot be named"
        )
    return sorted(zip(names, map(float, lengthscales), strict=True), key=lambda kv: kv[1]), None


def observed_points(
    store: Store, kb: str, type_id: str
) -> tuple[list[int], list[tuple[dict[str, Any], bool]]]:
    """The type's newest points (at most MAX_OVERLAY_POINTS), oldest first: their ids, and
    their decision values with their labels."""
    rows = browse.newest_points(store, kb, type_id, MAX_OVERLAY_POINTS)
    return [pid for pid, _, _ in rows], [(x, ok) for _, x, ok in rows]


def point_page(
    store: Store, hooks: ServiceHooks, kb: str, point_id: int, judge: Any | None
) -> dict[str, Any]:
    """One stored point: its type, label, decision values, provenance, and what the type's
    model now says at it (P(feasible) and its uncertainty; None without a model)."""
    point = browse.point_in_kb(store, kb, point_id)
    detail = types.get_type(store, kb, point.type_id)
    verdict = None
    if judge is not None and hooks.surrogate(kb, point.type_id) is not None:
        p, sd = judge(kb, point.type_id, [point.x])
        verdict = {"p": float(p[0]), "sd": float(sd[0])}
    return {
        "kb": kb,
        "point": point.model_dump(mode="json"),
        "detail": detail,
        "type_href": f"/ui/kbs/{quote(kb, safe='')}/types/{point.type_id}?hold={point_id}",
        "verdict": verdict,
    }


def compare(store: Store, a: str, b: str) -> dict[str, Any]:
    """Two knowledge bases side by side, a row per CP type (a type has one id in every base):
    each base's points and feasible share of it, and the change from the first to the second."""
    sides = {}
    for name in (a, b):
        page = browse.types_page(store, name, offset=0, limit=COMPARE_MAX_TYPES)
        sides[name] = {row.summary.type_id: row.summary for row in page.rows}
    ids = sorted(
        set(sides[a]) | set(sides[b]),
        key=lambda t: (-(sides[a].get(t) or sides[b][t]).n_points, t),
    )
    rows = []
    for type_id in ids:
        left, right = sides[a].get(type_id), sides[b].get(type_id)
        known = left if left is not None else sides[b][type_id]
        ratios = [None if s is None else feasible_ratio(s) for s in (left, right)]
        first, second = ratios
        rows.append(
            {
                "type_id": type_id,
                "failure": known.failure,
                "decisions": known.decisions,
                "sides": [
                    None if s is None else {"n": s.n_points, "ratio": r}
                    for s, r in zip((left, right), ratios, strict=True)
                ],
                "change": None if first is None or second is None else second - first,
            }
        )
    names = [k.name for k in kbs.list_kbs(store)]
    return {"a": a, "b": b, "rows": rows, "kbs": names, "max_types": COMPARE_MAX_TYPES}


COMPARE_MAX_TYPES = 500

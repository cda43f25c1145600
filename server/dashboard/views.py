"""What the dashboard shows, assembled from the service functions (no SQL here).

Each view is a plain dict handed to a Jinja2 template; the same dicts, minus the rendered
fragments, are the JSON that the page's script polls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict
from datetime import UTC, datetime
from typing import Any

from client.models import PointsPage, SurrogateState, TypeDetail, TypeSummary
from server.dashboard.heatmap import Dim, continuous_dims
from server.db import Store
from server.hooks import ServiceHooks
from server.services import activity, kbs, points, types
from server.services.types import load_training_points
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder

# (kb, type_id, decision values) -> P(feasible) per value, or None when no surrogate answers.
Predictor = Callable[[str, str, list[dict[str, Any]]], list[float] | None]
MAX_OVERLAY_POINTS = 2000


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
    """All knowledge bases, and the one to show: the requested, else `default`, else the first."""
    bases = kbs.list_kbs(store)
    names = [b.name for b in bases]
    if requested is not None:
        return bases, requested
    if kbs.DEFAULT_KB in names:
        return bases, kbs.DEFAULT_KB
    return bases, names[0] if names else None


def overview(store: Store, kb: str | None) -> dict[str, Any]:
    """The knowledge bases, the chosen one's types with provenance, and the recent workers."""
    bases, chosen = pick_kb(store, kb)
    type_rows = []
    if chosen is not None:
        for summary in types.list_types(store, chosen):
            prov = activity.type_provenance(store, chosen, summary.type_id, limit=3)
            type_rows.append(
                {
                    **summary.model_dump(mode="json"),
                    "feasible_ratio": feasible_ratio(summary),
                    "updated_ago": ago(summary.updated_at),
                    "provenance": asdict(prov),
                }
            )
    workers = [
        {**asdict(w), "last_seen": w.last_seen.isoformat(), "last_seen_ago": ago(w.last_seen)}
        for w in activity.recent_workers(store, limit=20)
    ]
    return {
        "kb": chosen,
        "kbs": [b.model_dump(mode="json") for b in bases],
        "types": type_rows,
        "workers": workers,
        "generated_at": datetime.now(UTC).isoformat(),
    }


def surrogate_state(hooks: ServiceHooks, kb: str, type_id: str) -> dict[str, Any] | None:
    state: SurrogateState | None = hooks.surrogate(kb, type_id)
    return None if state is None else state.model_dump(mode="json")


def type_status(store: Store, hooks: ServiceHooks, kb: str, type_id: str) -> dict[str, Any]:
    """The parts of a type page that change while points arrive: counts, provenance, surrogate."""
    detail: TypeDetail = types.get_type(store, kb, type_id)
    return {
        "kb": kb,
        "type_id": type_id,
        "n_points": detail.n_points,
        "n_infeasible": detail.n_infeasible,
        "feasible_ratio": feasible_ratio(detail),
        "updated_at": detail.updated_at.isoformat() if detail.updated_at else None,
        "updated_ago": ago(detail.updated_at),
        "provenance": asdict(activity.type_provenance(store, kb, type_id)),
        "surrogate": surrogate_state(hooks, kb, type_id),
    }


def dim_lengthscales(space: dict[str, Any], lengthscales: list[float] | None) -> dict[str, float]:
    """The fitted lengthscale of each continuous dimension (`#pose[1]` -> 0.3), read from the
    encoder's columns; empty without a fit or when the fit's columns do not match."""
    if not lengthscales:
        return {}
    encoder = SpaceEncoder(space_from_json({k: d.model_dump() for k, d in space.items()}))
    if len(lengthscales) != encoder.dim:
        return {}
    return {
        f"{var.name}[{i}]": float(lengthscales[var.start + i])
        for var in encoder.vars
        if var.table is None
        for i in range(var.width)
    }


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
    store: Store,
    hooks: ServiceHooks,
    kb: str,
    type_id: str,
    *,
    x: str | None,
    y: str | None,
    limit: int,
    cursor: str | None,
) -> dict[str, Any]:
    detail = types.get_type(store, kb, type_id)
    page: PointsPage = points.list_points(store, kb, type_id, limit=limit, cursor=cursor)
    dims = continuous_dims(detail.space)
    status = type_status(store, hooks, kb, type_id)
    relevance = dim_lengthscales(detail.space, (status["surrogate"] or {}).get("lengthscales"))
    dx, dy = choose_dims(dims, x, y, relevance)
    return {
        **status,
        "relevance": sorted(relevance.items(), key=lambda kv: kv[1]),
        "detail": detail,
        "space": {label: dom.model_dump(mode="json") for label, dom in detail.space.items()},
        "dims": [d.name for d in dims],
        "x_dim": dx.name if dx else None,
        "y_dim": dy.name if dy else None,
        "points": [p.model_dump(mode="json") for p in page.points],
        "next_cursor": page.next_cursor,
        "cursor": cursor,
        "limit": limit,
    }


def observed_points(store: Store, kb: str, type_id: str) -> list[tuple[dict[str, Any], bool]]:
    """The type's latest points (at most MAX_OVERLAY_POINTS) with their labels."""
    data = load_training_points(store, kb, type_id)
    pairs = list(zip(data.x, data.feasible, strict=True))
    return pairs[-MAX_OVERLAY_POINTS:]

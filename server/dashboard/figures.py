"""A type's pictures (heat map, slices, history) drawn from one read of what they need: the
type's space, the fit's lengthscales, its latest points, the surrogate's predict and
uncertainty, and the slice the other dimensions are held at."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from server.dashboard import views
from server.dashboard.heatmap import (
    Judge,
    Predict,
    Slice,
    choose_slice,
    continuous_dims,
    render_heatmap_svg,
    slice_at,
)
from server.dashboard.history_svg import render_history_svg
from server.dashboard.parallel import render_parallel_svg
from server.dashboard.slices import render_slices_svg
from server.db import Store
from server.hooks import ServiceHooks
from server.services import browse, types

# The surrogate engine's in-process predict: (kb, type_id, decision values) -> P(feasible);
# its predict_with_uncertainty has the same arguments (-> P(feasible), latent sd / prior sd).
EnginePredict = Callable[[str, str, list[dict[str, Any]]], Any]


@dataclass(frozen=True)
class Inputs:
    space: dict[str, Any]
    relevance: dict[str, float]
    observed: list[tuple[dict[str, Any], bool]]
    predict: Predict | None
    held: Slice
    judge: Judge | None = None


def predictor(engine: EnginePredict | None, kb: str, type_id: str) -> Predict | None:
    """One type's predict, None where no engine is installed (no surrogate yet)."""
    if engine is None:
        return None

    def run(xs: list[dict[str, Any]]) -> list[float]:
        return list(engine(kb, type_id, xs))

    return run


def judge_of(engine: EnginePredict | None, kb: str, type_id: str) -> Judge | None:
    """One type's P(feasible) and uncertainty at once, None without an engine."""
    if engine is None:
        return None

    def run(xs: list[dict[str, Any]]) -> tuple[list[float], list[float]]:
        p, sd = engine(kb, type_id, xs)
        return list(p), list(sd)

    return run


def inputs(
    store: Store,
    hooks: ServiceHooks,
    engine: EnginePredict | None,
    kb: str,
    type_id: str,
    judge: EnginePredict | None = None,
    hold: int | None = None,
) -> Inputs:
    """`hold`: the id of the point the pictures are drawn through (NotFound if the type has
    none such); by default the newest feasible point."""
    detail = types.get_type(store, kb, type_id)
    state = views.surrogate_state(hooks, kb, type_id) or {}
    ids, observed = views.observed_points(store, kb, type_id)
    if hold is None:
        held = choose_slice(detail.space, observed, ids)
    else:
        point = browse.one_point(store, kb, type_id, hold)
        held = slice_at(detail.space, point.x, f"point #{hold}, as chosen", hold)
    return Inputs(
        space=detail.space,
        relevance=views.dim_lengthscales(detail.space, state.get("lengthscales")),
        observed=observed,
        predict=predictor(engine, kb, type_id),
        held=held,
        judge=judge_of(judge, kb, type_id),
    )


def heatmap(f: Inputs, x: str | None, y: str | None, n: int, cols: int | None = None) -> str:
    dx, dy = views.choose_dims(continuous_dims(f.space), x, y, f.relevance)
    return render_heatmap_svg(
        f.space, dx, dy, f.predict, f.observed, n=n, held=f.held, judge=f.judge, cols=cols
    )


def slices(f: Inputs, cols: int | None = None) -> str:
    return render_slices_svg(f.space, f.predict, f.observed, f.held, f.relevance, cols)


def parallel(f: Inputs, fit_axes: int | None = None) -> str:
    return render_parallel_svg(f.space, f.observed, f.relevance, fit_axes)


def type_history(store: Store, kb: str, type_id: str, axis: str = "time", cols: int = 2) -> str:
    history = browse.history(store, kb, type_id, axis=axis)
    return render_history_svg(history, "task", narrow=cols < 2)


def kb_history(store: Store, kb: str, axis: str = "time", cols: int = 2) -> str:
    return render_history_svg(browse.history(store, kb, axis=axis), "type", narrow=cols < 2)

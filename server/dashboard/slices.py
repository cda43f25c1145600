"""The slice view of a CP type: one small panel per decision, most relevant first.

A continuous dimension's panel draws the surrogate's P(feasible) along that dimension, every
other decision held at the heat map's slice, with the stored points at their value (feasible
along the top, infeasible along the bottom, each faded by its distance from the held point in
the other decisions), as optuna's slice plot does for an objective.
Its title names the fit's lengthscale and a bar for its relevance (1 / lengthscale, scaled to
the most relevant dimension): which decisions matter, at a glance. A categorical decision's
panel shows each choice's stored feasible share and count.
"""

from __future__ import annotations

import math
import textwrap
from collections import Counter
from collections.abc import Sequence
from html import escape

from contract.models import CategoricalDomain, ContinuousDomain
from server.dashboard.heatmap import (
    FONT,
    HELD_COLOUR,
    Dim,
    Predict,
    Slice,
    Value,
    closeness,
    continuous_dims,
    opacity,
)

_W = 230.0
_H = 80.0
_PAD_L = 34.0
_PAD_T = 36.0
_PAD_B = 28.0
_GAP = 20.0
_STEPS = 40
_INK = "#111827"
_MUTED = "#6b7280"
_CURVE = "#0072b2"  # Okabe-Ito blue
_BAR = "#e69f00"  # Okabe-Ito orange
_BAD = "#cc79a7"  # Okabe-Ito reddish purple: an infeasible point, seen on light and dark pages


def _order(dims: list[Dim], relevance: dict[str, float]) -> list[Dim]:
    return sorted(dims, key=lambda d: relevance.get(d.name, math.inf))


def render_slices_svg(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    predict: Predict | None,
    observed: Sequence[tuple[dict[str, Value], bool]],
    held: Slice,
    relevance: dict[str, float],
    cols: int | None = None,
) -> str:
    """All panels in rows of `cols` (three by default; one on a phone, so that they stack
    rather than shrink), one predict call for every curve."""
    dims = _order(continuous_dims(space), relevance)
    choices = held.choices
    queries: list[dict[str, Value]] = []
    for dim in dims:
        for k in range(_STEPS + 1):
            vectors = {lab: list(v) for lab, v in held.values.items()}
            vectors[dim.label][dim.index] = dim.low + (dim.high - dim.low) * k / _STEPS
            queries.append({**vectors, **choices})
    probs = predict(queries) if predict is not None and queries else []
    cats = [(lab, d) for lab, d in space.items() if isinstance(d, CategoricalDomain)]
    n_panels = len(dims) + len(cats)
    cols = max(1, min(cols or 3, n_panels))
    rows = max(1, math.ceil(n_panels / cols))
    cell_w, cell_h = _PAD_L + _W + _GAP, _PAD_T + _H + _PAD_B
    width = cols * cell_w
    top = min(relevance.values()) if relevance else None
    out = [""]  # the opening tag, once the note's height is known
    for k, dim in enumerate(dims):
        ox, oy = (k % cols) * cell_w + _PAD_L, (k // cols) * cell_h + _PAD_T
        curve = probs[k * (_STEPS + 1) : (k + 1) * (_STEPS + 1)]
        fades = [closeness(space, x, held, {dim.name}, with_choices=True) for x, _ in observed]
        out.append(
            _continuous_panel(
                ox, oy, dim, curve, observed, fades, held, relevance.get(dim.name), top
            )
        )
    for j, (label, domain) in enumerate(cats):
        k = len(dims) + j
        ox, oy = (k % cols) * cell_w + _PAD_L, (k // cols) * cell_h + _PAD_T
        out.append(_choice_panel(ox, oy, label, domain, observed))
    note = "other decisions held at " + held.origin
    if held.point_id is not None:
        note += " (dashed; a faded point lies far from it in them)"
    if choices:
        note += " (" + ", ".join(f"{lab}={c}" for lab, c in choices.items()) + ")"
    if predict is None:
        note += "; no surrogate yet: stored points only"
    # Wrapped to the picture's width (about 6 px a character at 11 px).
    lines = textwrap.wrap(note, width=max(30, int((width - 12) / 6.2)))
    height = rows * cell_h + 8 + 14 * len(lines)
    tspans = "".join(
        f'<tspan x="6" dy="{0 if k == 0 else 14}">{escape(line)}</tspan>'
        for k, line in enumerate(lines)
    )
    out.append(
        f'<text class="cp-slice-note" x="6" y="{rows * cell_h + 6:.0f}" font-size="11" '
        f'fill="{_MUTED}">{tspans}</text></svg>'
    )
    out[0] = (
        f'<svg class="cp-slices" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="slices of P(feasible), one per decision" font-family="{FONT}">'
    )
    return "".join(out)


def _title(ox: float, oy: float, name: str, ell: float | None, top: float | None) -> str:
    parts = [
        f'<text x="{ox:.1f}" y="{oy - 22:.1f}" font-size="12" fill="{_INK}">{escape(name)}'
        + (f' <tspan fill="{_MUTED}">lengthscale {ell:.3g}</tspan>' if ell is not None else "")
        + "</text>"
    ]
    if ell is not None and top is not None and ell > 0:
        share = top / ell
        parts.append(
            f'<rect class="cp-relevance" data-relevance="{share:.3f}" x="{ox:.1f}" '
            f'y="{oy - 16:.1f}" width="{_W * share:.1f}" height="5" fill="{_BAR}">'
            f"<title>relevance {share:.2f} of the most relevant dimension</title></rect>"
        )
    return "".join(parts)


def _frame(ox: float, oy: float, low: str, high: str) -> str:
    return (
        f'<rect x="{ox:.1f}" y="{oy:.1f}" width="{_W}" height="{_H}" fill="none" '
        f'stroke="{_MUTED}" stroke-width="0.8"/>'
        f'<text x="{ox - 4:.1f}" y="{oy + 8:.1f}" font-size="9" text-anchor="end" '
        f'fill="{_MUTED}">1</text>'
        f'<text x="{ox - 4:.1f}" y="{oy + _H:.1f}" font-size="9" text-anchor="end" '
        f'fill="{_MUTED}">0</text>'
        f'<text x="{ox:.1f}" y="{oy + _H + 12:.1f}" font-size="9" fill="{_MUTED}">{low}</text>'
        f'<text x="{ox + _W:.1f}" y="{oy + _H + 12:.1f}" font-size="9" text-anchor="end" '
        f'fill="{_MUTED}">{high}</text>'
    )


def _continuous_panel(
    ox: float,
    oy: float,
    dim: Dim,
    curve: list[float],
    observed: Sequence[tuple[dict[str, Value], bool]],
    fades: Sequence[float],
    held: Slice,
    ell: float | None,
    top: float | None,
) -> str:
    parts = [
        f'<g class="cp-slice-panel" data-dim="{escape(dim.name)}">',
        _title(ox, oy, dim.name, ell, top),
        _frame(ox, oy, f"{dim.low:.3g}", f"{dim.high:.3g}"),
    ]
    if curve:
        pts = " ".join(
            f"{ox + _W * k / _STEPS:.1f},{oy + _H * (1 - min(max(p, 0.0), 1.0)):.1f}"
            for k, p in enumerate(curve)
        )
        parts.append(
            f'<polyline class="cp-slice-curve" points="{pts}" fill="none" stroke="{_CURVE}" '
            'stroke-width="1.8"/>'
        )
    span = dim.high - dim.low or 1.0
    if held.point_id is not None:
        hx = ox + _W * (held.values[dim.label][dim.index] - dim.low) / span
        parts.append(
            f'<line class="cp-held" data-point-id="{held.point_id}" x1="{hx:.1f}" '
            f'y1="{oy:.1f}" x2="{hx:.1f}" y2="{oy + _H:.1f}" stroke="{HELD_COLOUR}" '
            f'stroke-width="1.5" stroke-dasharray="3 2"><title>the held point '
            f"#{held.point_id}</title></line>"
        )
    for n, (x, feasible) in enumerate(observed):
        v = x.get(dim.label)
        if not isinstance(v, list) or len(v) <= dim.index:
            continue
        px = ox + _W * (float(v[dim.index]) - dim.low) / span
        jitter = (n * 7 % 11) - 5  # spread stacked points a little, reproducibly
        py = oy + (4 + jitter / 2 if feasible else _H - 4 + jitter / 2)
        parts.append(
            f'<circle class="cp-slice-point" data-feasible="{int(feasible)}" cx="{px:.1f}" '
            f'cy="{py:.1f}" r="2.2" fill="{"#ffffff" if feasible else _BAD}" '
            f'stroke="{_INK}" stroke-width="0.8" data-closeness="{fades[n]:.2f}" '
            f'opacity="{opacity(fades[n]):.2f}"/>'
        )
    parts.append("</g>")
    return "".join(parts)


def _choice_panel(
    ox: float,
    oy: float,
    label: str,
    domain: CategoricalDomain,
    observed: Sequence[tuple[dict[str, Value], bool]],
) -> str:
    total: Counter[str] = Counter()
    good: Counter[str] = Counter()
    for point, feasible in observed:
        choice = point.get(label)
        if isinstance(choice, str):
            total[choice] += 1
            good[choice] += int(feasible)
    parts = [
        f'<g class="cp-slice-panel" data-dim="{escape(label)}">',
        f'<text x="{ox:.1f}" y="{oy - 22:.1f}" font-size="12" fill="{_INK}">{escape(label)}</text>',
        # A line of its own: beside a long label it would run past the panel on a phone.
        f'<text x="{ox:.1f}" y="{oy - 7:.1f}" font-size="9" fill="{_MUTED}">'
        "stored feasible share, points per choice</text>",
        _frame(ox, oy, "", ""),
    ]
    bar_w = _W / max(1, len(domain.choices))
    for i, choice in enumerate(domain.choices):
        n = total[choice]
        share = good[choice] / n if n else 0.0
        left = ox + i * bar_w
        parts.append(
            f'<rect class="cp-choice-bar" x="{left + 3:.1f}" y="{oy + _H * (1 - share):.1f}" '
            f'width="{bar_w - 6:.1f}" height="{_H * share:.1f}" fill="{_CURVE}" '
            f'fill-opacity="0.7"><title>{escape(choice)}: {good[choice]} of {n} feasible'
            "</title></rect>"
            f'<text x="{left + bar_w / 2:.1f}" y="{oy + _H + 12:.1f}" font-size="9" '
            f'text-anchor="middle" fill="{_INK}">{escape(_fit(choice, bar_w))}</text>'
            f'<text x="{left + bar_w / 2:.1f}" y="{oy + _H + 22:.1f}" font-size="9" '
            f'text-anchor="middle" fill="{_MUTED}">{n}</text>'
        )
    parts.append("</g>")
    return "".join(parts)


def _fit(text: str, width: float) -> str:
    """`text` cut to what `width` px hold at the 9 px font (an ellipsis marks the cut)."""
    room = max(1, int(width / 5.4))
    return text if len(text) <= room else text[: room - 1] + "…"

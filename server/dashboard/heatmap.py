"""The feasibility picture of a CP type: P(feasible) over two continuous dimensions, one panel per
categorical choice, with the stored points drawn on top. Rendered as SVG rects (no image files).

A type's decision space maps labels to domains; a continuous domain is a box, so each of its
components is one dimension, named `label[i]`. The two chosen dimensions span the grid; every
other continuous component is held at the middle of its range, and each panel fixes one
combination of the categorical choices.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from html import escape

from client.models import CategoricalDomain, ContinuousDomain

Value = str | list[float]
Predict = Callable[[list[dict[str, Value]]], list[float]]

MAX_PANELS = 12
_PANEL_PX = 180.0  # a 2-d panel's side
_STRIP_PX = 40.0  # the height of a 1-d strip, the side of a choice-only cell
_PAD_LEFT = 46.0
_PAD_TOP = 30.0
_PAD_BOTTOM = 34.0
_PANEL_GAP = 24.0


@dataclass(frozen=True)
class Dim:
    """One continuous component: `label[index]` with its bounds."""

    label: str
    index: int
    low: float
    high: float

    @property
    def name(self) -> str:
        return f"{self.label}[{self.index}]"


def continuous_dims(space: dict[str, CategoricalDomain | ContinuousDomain]) -> list[Dim]:
    dims: list[Dim] = []
    for label, domain in space.items():
        if isinstance(domain, ContinuousDomain):
            dims.extend(
                Dim(label, i, lo, hi)
                for i, (lo, hi) in enumerate(zip(domain.low, domain.high, strict=True))
            )
    return dims


def panels_of(space: dict[str, CategoricalDomain | ContinuousDomain]) -> list[dict[str, str]]:
    """Every combination of categorical choices (at most MAX_PANELS), in the domain's order."""
    cats = [(lab, d.choices) for lab, d in space.items() if isinstance(d, CategoricalDomain)]
    combos = itertools.product(*(choices for _, choices in cats))
    labels = [lab for lab, _ in cats]
    return [dict(zip(labels, combo, strict=True)) for combo in itertools.islice(combos, MAX_PANELS)]


def grid_points(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    dx: Dim | None,
    dy: Dim | None,
    panel: dict[str, str],
    n: int,
) -> list[dict[str, Value]]:
    """n x n decision values (row-major, y from high to low so that rows draw top-down); one
    value when there is no continuous dimension at all."""
    mids = {
        lab: [(lo + hi) / 2.0 for lo, hi in zip(d.low, d.high, strict=True)]
        for lab, d in space.items()
        if isinstance(d, ContinuousDomain)
    }
    if dx is None:
        return [{**mids, **panel}]
    xs = [dx.low + (dx.high - dx.low) * (i + 0.5) / n for i in range(n)]
    rows = 1 if dy is None else n
    ys = [0.0] if dy is None else [dy.high - (dy.high - dy.low) * (j + 0.5) / n for j in range(n)]
    points: list[dict[str, Value]] = []
    for j in range(rows):
        for i in range(n):
            vectors = {lab: list(v) for lab, v in mids.items()}
            vectors[dx.label][dx.index] = xs[i]
            if dy is not None:
                vectors[dy.label][dy.index] = ys[j]
            points.append({**vectors, **panel})
    return points


NO_MODEL_COLOUR = "#e5e7eb"


@functools.cache
def _palette() -> tuple[str, ...]:
    """101 colours of matplotlib's RdYlGn, red (infeasible) through yellow to green (feasible)."""
    from matplotlib import colormaps

    cmap = colormaps["RdYlGn"]
    return tuple(
        "#{:02x}{:02x}{:02x}".format(*(round(c * 255) for c in cmap(k / 100)[:3]))
        for k in range(101)
    )


def _colour(p: float) -> str:
    """The palette's colour for a probability (to 0.01); grey for no prediction (NaN)."""
    if math.isnan(p):
        return NO_MODEL_COLOUR
    return _palette()[round(min(max(p, 0.0), 1.0) * 100)]


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def render_heatmap_svg(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    dx: Dim | None,
    dy: Dim | None,
    predict: Predict | None,
    observed: Sequence[tuple[dict[str, Value], bool]] = (),
    n: int = 20,
) -> str:
    """Panels side by side (wrapping after four), one predict call for all of them. With no
    `predict` (no surrogate yet) the cells are grey and only the stored points show."""
    panels = panels_of(space)
    if dx is None:
        n = 1
    rows = 1 if dy is None else n
    per_panel = n * rows
    queries = [p for panel in panels for p in grid_points(space, dx, dy, panel, n)]
    probs = predict(queries) if predict is not None else [math.nan] * len(queries)
    if len(probs) != len(queries):
        raise ValueError("predict answered a different number of probabilities")
    w = _PANEL_PX if dx is not None else _STRIP_PX
    h = _PANEL_PX if dy is not None else _STRIP_PX
    cell_w, cell_h = w / n, h / rows
    panel_w = _PAD_LEFT + w + _PANEL_GAP
    panel_h = _PAD_TOP + h + _PAD_BOTTOM
    cols = min(len(panels), 4)
    width = cols * panel_w + 10
    height = ((len(panels) + cols - 1) // cols) * panel_h + 28
    out = [
        f'<svg class="cp-heatmap" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="P(feasible) heat map">'
    ]
    for k, panel in enumerate(panels):
        ox = (k % cols) * panel_w + _PAD_LEFT
        oy = (k // cols) * panel_h + _PAD_TOP
        title = ", ".join(f"{lab}={choice}" for lab, choice in panel.items()) or "all"
        out.append(f'<g class="cp-heatmap-panel" data-panel="{escape(title)}">')
        out.append(
            f'<text x="{ox:.1f}" y="{oy - 10:.1f}" font-size="12" fill="#111827">'
            f"{escape(title)}</text>"
        )
        chunk = probs[k * per_panel : (k + 1) * per_panel]
        for idx, p in enumerate(chunk):
            j, i = divmod(idx, n)
            tip = "no surrogate yet" if math.isnan(p) else f"p={p:.2f}"
            out.append(
                f'<rect x="{ox + i * cell_w:.2f}" y="{oy + j * cell_h:.2f}" '
                f'width="{cell_w + 0.3:.2f}" height="{cell_h + 0.3:.2f}" fill="{_colour(p)}">'
                f"<title>{tip}</title></rect>"
            )
        if dx is not None:
            out.append(_axes(ox, oy, w, h, dx, dy))
            out.append(_observed_marks(ox, oy, w, h, dx, dy, panel, observed))
        out.append("</g>")
    swatches = "".join(f'<tspan fill="{_colour(p / 10)}">■</tspan>' for p in range(11))
    out.append(
        f'<text x="10" y="{height - 12:.0f}" font-size="11" fill="#374151">'
        f"P(feasible): 0 {swatches} 1 · dots: stored points (green feasible, red infeasible)"
        " · other dimensions at mid-range</text>"
    )
    out.append("</svg>")
    return "".join(out)


def _axes(ox: float, oy: float, w: float, h: float, dx: Dim, dy: Dim | None) -> str:
    parts = [
        f'<rect x="{ox:.1f}" y="{oy:.1f}" width="{w:.1f}" height="{h:.1f}" fill="none" '
        'stroke="#374151" stroke-width="0.8"/>',
        f'<text x="{ox:.1f}" y="{oy + h + 12:.1f}" font-size="10">{_fmt(dx.low)}</text>',
        f'<text x="{ox + w:.1f}" y="{oy + h + 12:.1f}" font-size="10" text-anchor="end">'
        f"{_fmt(dx.high)}</text>",
        f'<text x="{ox + w / 2:.1f}" y="{oy + h + 26:.1f}" font-size="11" text-anchor="middle">'
        f"{escape(dx.name)}</text>",
    ]
    if dy is not None:
        parts += [
            f'<text x="{ox - 4:.1f}" y="{oy + h:.1f}" font-size="10" text-anchor="end">'
            f"{_fmt(dy.low)}</text>",
            f'<text x="{ox - 4:.1f}" y="{oy + 9:.1f}" font-size="10" text-anchor="end">'
            f"{_fmt(dy.high)}</text>",
            f'<text x="{ox - 8:.1f}" y="{oy + h / 2:.1f}" font-size="11" text-anchor="end">'
            f"{escape(dy.name)}</text>",
        ]
    return "".join(parts)


def _observed_marks(
    ox: float,
    oy: float,
    w: float,
    h: float,
    dx: Dim,
    dy: Dim | None,
    panel: dict[str, str],
    observed: Sequence[tuple[dict[str, Value], bool]],
) -> str:
    marks: list[str] = []
    for x, feasible in observed:
        if any(x.get(lab) != choice for lab, choice in panel.items()):
            continue
        vx = x.get(dx.label)
        if not isinstance(vx, list) or len(vx) <= dx.index:
            continue
        px = ox + (vx[dx.index] - dx.low) / (dx.high - dx.low) * w
        py = oy + h / 2.0
        if dy is not None:
            vy = x.get(dy.label)
            if not isinstance(vy, list) or len(vy) <= dy.index:
                continue
            py = oy + (dy.high - vy[dy.index]) / (dy.high - dy.low) * h
        colour = "#15803d" if feasible else "#b91c1c"
        marks.append(
            f'<circle class="cp-observed" cx="{px:.1f}" cy="{py:.1f}" r="2.6" fill="{colour}" '
            'stroke="#ffffff" stroke-width="0.8"/>'
        )
    return "".join(marks)

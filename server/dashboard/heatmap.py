"""The feasibility picture of a CP type: P(feasible) over two continuous dimensions, one panel per
categorical choice, with the stored points drawn on top. Rendered as SVG rects (no image files).

A type's decision space maps labels to domains; a continuous domain is a box, so each of its
components is one dimension, named `label[i]`. The two chosen dimensions span the grid; every
other continuous component is held at a stated slice (`Slice`: the latest infeasible point, so
that the map passes through a known failure), and each panel fixes one combination of the
categorical choices. Every panel is drawn; its point count is in its title.

Where the model is unsure, because no data bears on a cell (its latent posterior sd is more than
`UNSURE_SD` of the prior's: `FeasibilityPredictor.uncertainty`), the cell is washed out and
hatched, and the legend says why: its colour there is the model's extrapolation, not knowledge.
The colour itself stays P(feasible) on the cividis scale.
"""

from __future__ import annotations

import functools
import itertools
import math
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from html import escape

from contract.models import CategoricalDomain, ContinuousDomain

Value = str | list[float]
Predict = Callable[[list[dict[str, Value]]], list[float]]
# Decision values -> P(feasible) and the model's latent posterior sd over its prior sd, in [0, 1].
Judge = Callable[[list[dict[str, Value]]], tuple[list[float], list[float]]]

_PANEL_PX = 180.0  # a 2-d panel's side
_STRIP_PX = 40.0  # the height of a 1-d strip, the side of a choice-only cell
_CELL_PX = 80.0  # the width of a choice-only cell, room for its counts
_COUNT_PX = 22.0
_LEGEND_W = 480.0
FEW_POINTS = 5  # a panel with fewer points says so
UNSURE_SD = math.sqrt(0.5)  # unsure where the data explains less than half the prior variance
HATCH_ID = "cp-unsure-hatch"
FONT = "system-ui, -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif"
_PAD_LEFT = 46.0
_PAD_TOP = 30.0
_PAD_BOTTOM = 34.0
_PANEL_GAP = 24.0
_SMALL_CHAR_W = 6.4  # px per character at the 11 px legend font, a little generous


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
    """Every combination of categorical choices, in the domain's order."""
    cats = [(lab, d.choices) for lab, d in space.items() if isinstance(d, CategoricalDomain)]
    combos = itertools.product(*(choices for _, choices in cats))
    labels = [lab for lab, _ in cats]
    return [dict(zip(labels, combo, strict=True)) for combo in combos]


@dataclass(frozen=True)
class Slice:
    """The point the dimensions off the axes are held at: its continuous values, its choices
    (the slices hold them; the heat map draws a panel per choice), where it comes from, and
    its id when it is a stored point."""

    values: dict[str, list[float]]
    origin: str
    choices: dict[str, str] = field(default_factory=dict)
    point_id: int | None = None


def mid_range(space: dict[str, CategoricalDomain | ContinuousDomain]) -> dict[str, list[float]]:
    return {
        lab: [(lo + hi) / 2.0 for lo, hi in zip(d.low, d.high, strict=True)]
        for lab, d in space.items()
        if isinstance(d, ContinuousDomain)
    }


def _first_choices(space: dict[str, CategoricalDomain | ContinuousDomain]) -> dict[str, str]:
    return {lab: d.choices[0] for lab, d in space.items() if isinstance(d, CategoricalDomain)}


def slice_at(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    x: dict[str, Value],
    origin: str,
    point_id: int | None = None,
) -> Slice:
    """The slice through decision values `x` (a stored point's)."""
    values = {lab: [float(v) for v in x[lab]] for lab in mid_range(space)}
    choices = {lab: str(x[lab]) for lab in _first_choices(space)}
    return Slice(values, origin, choices, point_id)


def choose_slice(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    observed: Sequence[tuple[dict[str, Value], bool]],
    ids: Sequence[int] | None = None,
) -> Slice:
    """The default slice: through the newest feasible point (the map then shows what the model
    makes of a known success, where a planner wants to be), else the newest point, else
    mid-range. `ids` are the observed points' ids, oldest first, to name the point."""
    for k in range(len(observed) - 1, -1, -1):
        x, feasible = observed[k]
        if feasible:
            point_id = ids[k] if ids is not None else None
            return slice_at(space, x, _named(point_id, "the newest feasible point"), point_id)
    if observed:
        point_id = ids[-1] if ids is not None else None
        return slice_at(space, observed[-1][0], _named(point_id, "the newest point"), point_id)
    return Slice(mid_range(space), "mid-range", _first_choices(space))


def _named(point_id: int | None, what: str) -> str:
    return what if point_id is None else f"point #{point_id}, {what}"


FADE_REACH = 0.5  # a point this far (RMS, in units of each dimension's range) is faded most
FADE_FLOOR = 0.15  # the opacity of a point far from the slice: still there, plainly not on it


def closeness(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    x: dict[str, Value],
    held: Slice,
    shown: set[str],
    with_choices: bool,
) -> float:
    """How near `x` lies to the slice in the dimensions the picture does not show: 1 on it,
    falling to 0 at FADE_REACH (root mean square over the hidden continuous components, each
    scaled to its range, and, `with_choices`, 1 for each choice that differs)."""
    gaps: list[float] = []
    for lab, domain in space.items():
        if isinstance(domain, ContinuousDomain):
            v = x.get(lab)
            if not isinstance(v, list):
                continue
            for i, (lo, hi) in enumerate(zip(domain.low, domain.high, strict=True)):
                if f"{lab}[{i}]" in shown or i >= len(v):
                    continue
                span = (hi - lo) or 1.0
                gaps.append((float(v[i]) - held.values[lab][i]) / span)
        elif with_choices and lab in held.choices:
            gaps.append(0.0 if x.get(lab) == held.choices[lab] else 1.0)
    if not gaps:
        return 1.0
    rms = math.sqrt(sum(g * g for g in gaps) / len(gaps))
    return max(0.0, 1.0 - rms / FADE_REACH)


def opacity(near: float) -> float:
    return FADE_FLOOR + (1.0 - FADE_FLOOR) * near


def grid_points(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    dx: Dim | None,
    dy: Dim | None,
    panel: dict[str, str],
    n: int,
    held: dict[str, list[float]] | None = None,
) -> list[dict[str, Value]]:
    """n x n decision values (row-major, y from high to low so that rows draw top-down), the
    other dimensions at `held` (mid-range by default); one value without continuous dims."""
    mids = held if held is not None else mid_range(space)
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
PALETTE_NAME = "cividis"


@functools.cache
def _palette() -> tuple[str, ...]:
    """101 colours of matplotlib's cividis, dark blue (infeasible) to yellow (feasible):
    readable with every common colour-vision deficiency and in grey."""
    from matplotlib import colormaps

    cmap = colormaps[PALETTE_NAME]
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


def _in_panel(x: dict[str, Value], panel: dict[str, str]) -> bool:
    return all(x.get(lab) == choice for lab, choice in panel.items())


def render_heatmap_svg(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    dx: Dim | None,
    dy: Dim | None,
    predict: Predict | None,
    observed: Sequence[tuple[dict[str, Value], bool]] = (),
    n: int = 20,
    held: Slice | None = None,
    judge: Judge | None = None,
    cols: int | None = None,
) -> str:
    """Panels side by side (wrapping after `cols`, by default four: one on a phone, so that
    they stack rather than shrink), one predict call for all of them. With no
    `predict` (no surrogate yet) the cells are grey and only the stored points show. A panel
    without points is faded and says so: its colours are the model's extrapolation. A `judge`
    answers instead of `predict` with the model's uncertainty too: its unsure cells are hatched."""
    panels = panels_of(space)
    held = held or Slice(mid_range(space), "mid-range")
    if dx is None:
        n = 1
    rows = 1 if dy is None else n
    per_panel = n * rows
    queries = [p for panel in panels for p in grid_points(space, dx, dy, panel, n, held.values)]
    sds: list[float] | None = None
    if judge is not None:
        probs, sds = judge(queries)
    else:
        probs = predict(queries) if predict is not None else [math.nan] * len(queries)
    if len(probs) != len(queries) or (sds is not None and len(sds) != len(queries)):
        raise ValueError("the model answered a different number of values than asked")
    w = _PANEL_PX if dx is not None else _CELL_PX
    h = _PANEL_PX if dy is not None else _STRIP_PX
    cell_w, cell_h = w / n, h / rows
    panel_w = _PAD_LEFT + w + _PANEL_GAP
    panel_h = _PAD_TOP + h + (_PAD_BOTTOM if dx is not None else _COUNT_PX)
    cols = max(1, min(len(panels), cols or (4 if dx is not None else 6)))
    narrow = cols * panel_w + 10 < _LEGEND_W
    width = cols * panel_w + 10 if narrow else max(cols * panel_w + 10, _LEGEND_W)
    legend_y = ((len(panels) + cols - 1) // cols) * panel_h + 8
    slice_lines = textwrap.wrap(
        f"other dimensions held at {held.origin}"
        + (" (ringed; a faded point lies far from it in them)" if held.point_id else "")
        + f": {_slice_text(held.values)}",
        width=max(30, int((width - 20) / _SMALL_CHAR_W)),
    )
    height = legend_y + 30 + 14 * len(slice_lines) + _legend_extra(sds is not None, narrow)
    out = [
        f'<svg class="cp-heatmap" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="P(feasible) heat map" font-family="{FONT}">'
    ]
    if sds is not None:
        out.append(_HATCH)
    for k, panel in enumerate(panels):
        ox = (k % cols) * panel_w + _PAD_LEFT
        oy = (k // cols) * panel_h + _PAD_TOP
        mine = [ok for x, ok in observed if _in_panel(x, panel)]
        title = ", ".join(f"{lab}={choice}" for lab, choice in panel.items()) or "all"
        few = len(mine) < FEW_POINTS
        note = "no data" if not mine else f"{len(mine)} pts" + (", few" if few else "")
        fade = "" if mine else ' opacity="0.55"'
        out.append(
            f'<g class="cp-heatmap-panel" data-panel="{escape(title)}" '
            f'data-n-points="{len(mine)}"{fade}>'
        )
        out.append(
            f'<text x="{ox:.1f}" y="{oy - 10:.1f}" font-size="12" fill="#111827">'
            f'{escape(title)} <tspan fill="#6b7280">({note})</tspan></text>'
        )
        chunk = probs[k * per_panel : (k + 1) * per_panel]
        sd_chunk = sds[k * per_panel : (k + 1) * per_panel] if sds is not None else None
        for idx, p in enumerate(chunk):
            j, i = divmod(idx, n)
            sd = sd_chunk[idx] if sd_chunk is not None else None
            out.append(_cell(ox + i * cell_w, oy + j * cell_h, cell_w, cell_h, p, sd))
        if sd_chunk is not None:
            out.append(_unsure_overlay(ox, oy, cell_w, cell_h, n, sd_chunk))
        if dx is not None:
            out.append(_axes(ox, oy, w, h, dx, dy))
            out.append(_observed_marks(ox, oy, w, h, dx, dy, panel, observed, space, held))
        else:
            n_bad = mine.count(False)
            out.append(
                f'<text class="cp-counts" x="{ox:.1f}" y="{oy + h + 14:.1f}" font-size="11" '
                f'fill="#111827">{len(mine) - n_bad} ✓ · {n_bad} ✗</text>'
            )
        out.append("</g>")
    out.append(_legend(legend_y, slice_lines, sds is not None, narrow))
    out.append("</svg>")
    return "".join(out)


def _cell(x: float, y: float, w: float, h: float, p: float, sd: float | None) -> str:
    """One grid cell, coloured by `p`; its tooltip and data attributes carry p and the sd."""
    tip = "no surrogate yet" if math.isnan(p) else f"p={p:.2f}"
    data = "" if math.isnan(p) else f' data-p="{p:.3f}"'
    if sd is not None and not math.isnan(p):
        tip += f" · sd {sd:.2f}"
        if sd > UNSURE_SD:
            data += ' data-unsure="1"'
            tip += ": unsure"
    return (
        f'<rect class="cp-cell" x="{x:.2f}" y="{y:.2f}" width="{w + 0.3:.2f}" '
        f'height="{h + 0.3:.2f}" fill="{_colour(p)}"{data}><title>{tip}</title></rect>'
    )


# A white wash under dark diagonal lines: lighter on the dark end of cividis, striped on its
# bright end, so that an unsure cell stands out at any P(feasible) and in grey.
_HATCH = (
    f'<defs><pattern id="{HATCH_ID}" width="6" height="6" patternUnits="userSpaceOnUse" '
    'patternTransform="rotate(45)"><rect width="6" height="6" fill="#ffffff" '
    'fill-opacity="0.4"/><line x1="0" y1="0" x2="0" y2="6" stroke="#111827" '
    'stroke-width="1.6" stroke-opacity="0.55"/></pattern></defs>'
)
_UNSURE_ROW = 18.0


def _unsure_overlay(
    ox: float, oy: float, cell_w: float, cell_h: float, n: int, sds: Sequence[float]
) -> str:
    """The hatch over the unsure cells, one rect per run of them along a row; it lets the
    pointer through to the cells' tooltips."""
    runs: list[str] = []
    for j in range(len(sds) // n):
        i = 0
        while i < n:
            if sds[j * n + i] <= UNSURE_SD or math.isnan(sds[j * n + i]):
                i += 1
                continue
            start = i
            while i < n and sds[j * n + i] > UNSURE_SD:
                i += 1
            runs.append(
                f'<rect class="cp-unsure" x="{ox + start * cell_w:.2f}" y="{oy + j * cell_h:.2f}" '
                f'width="{(i - start) * cell_w + 0.3:.2f}" height="{cell_h + 0.3:.2f}" '
                f'fill="url(#{HATCH_ID})" pointer-events="none"/>'
            )
    return "".join(runs)


def _legend_extra(with_unsure: bool, narrow: bool) -> float:
    """The legend's height beyond its scale row: the unsure row, and on a narrow picture the
    markers' own row and the unsure text's second line."""
    extra = _UNSURE_ROW if with_unsure else 0.0
    if narrow:
        extra += _UNSURE_ROW + (14.0 if with_unsure else 0.0)
    return extra


def _legend(y: float, slice_lines: list[str], with_unsure: bool, narrow: bool = False) -> str:
    """The scale, the markers (beside it, or below it on a narrow picture), the unsure hatch
    and the slice, each row below the last."""
    swatches = "".join(
        f'<rect x="{96 + 12 * k}" y="{y}" width="12" height="10" fill="{_colour(k / 10)}"/>'
        for k in range(11)
    )
    # Wrapped to the picture's width: one long line would run out of it.
    lines = "".join(
        f'<tspan x="10" dy="{0 if k == 0 else 14}">{escape(line)}</tspan>'
        for k, line in enumerate(slice_lines)
    )
    marks_y, marks_x = (y + _UNSURE_ROW, 14.0) if narrow else (y, 250.0)
    unsure = ""
    below = marks_y
    if with_unsure:
        row = marks_y + _UNSURE_ROW
        sd_note = f"(latent sd over {UNSURE_SD:.0%} of the prior's)"
        text = (
            f'<tspan x="40" dy="0">unsure: little data nearby</tspan>'
            f'<tspan x="40" dy="14">{sd_note}</tspan>'
            if narrow
            else f"unsure: little data nearby {sd_note}"
        )
        # The hatch over a mid-scale swatch, as it shows over the map.
        unsure = (
            f'<g class="cp-legend-unsure"><rect x="10" y="{row}" width="24" height="10" '
            f'fill="{_colour(0.5)}"/><rect x="10" y="{row}" width="24" height="10" '
            f'fill="url(#{HATCH_ID})" stroke="#374151" stroke-width="0.5"/>'
            f'<text x="40" y="{row + 9}">{text}</text></g>'
        )
        below = row + (14 if narrow else 0)
    slice_y = below + 28
    cross_x = marks_x + 100
    return (
        f'<g class="cp-legend" font-size="11" fill="#374151">'
        f'<text x="10" y="{y + 9}">P(feasible): 0</text>{swatches}'
        f'<text x="{96 + 12 * 11 + 4}" y="{y + 9}">1</text>'
        f'<circle cx="{marks_x}" cy="{marks_y + 5}" r="3.5" fill="#ffffff" stroke="#111827"/>'
        f'<text x="{marks_x + 8}" y="{marks_y + 9}">feasible point</text>'
        f'<path class="cp-legend-cross" d="{_cross(cross_x, marks_y + 5)}" stroke="#ffffff" '
        'stroke-width="3.2"/>'
        f'<path d="{_cross(cross_x, marks_y + 5)}" stroke="#111827" stroke-width="1.6"/>'
        f'<text x="{cross_x + 8}" y="{marks_y + 9}">infeasible point</text>'
        f'{unsure}<text class="cp-slice" x="10" y="{slice_y}">{lines}</text></g>'
    )


def _slice_text(values: dict[str, list[float]]) -> str:
    return "; ".join(f"{lab}=[{', '.join(_fmt(v) for v in vs)}]" for lab, vs in values.items())


def _cross(x: float, y: float, r: float = 3.5) -> str:
    a, b, c, d = x - r, x + r, y - r, y + r
    return f"M{a:.1f},{c:.1f} L{b:.1f},{d:.1f} M{a:.1f},{d:.1f} L{b:.1f},{c:.1f}"


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
            # Turned upright beside the ticks: a long name written across would leave the panel.
            f'<text x="{ox - 34:.1f}" y="{oy + h / 2:.1f}" font-size="11" text-anchor="middle" '
            f'transform="rotate(-90 {ox - 34:.1f} {oy + h / 2:.1f})">{escape(dy.name)}</text>',
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
    space: dict[str, CategoricalDomain | ContinuousDomain],
    held: Slice,
) -> str:
    """The stored points of this panel, each faded by its distance from the slice in the
    dimensions off the axes, and a ring where the held point lies."""
    shown = {dx.name} | ({dy.name} if dy is not None else set())

    def at(x: dict[str, Value]) -> tuple[float, float] | None:
        vx = x.get(dx.label)
        if not isinstance(vx, list) or len(vx) <= dx.index:
            return None
        px = ox + (vx[dx.index] - dx.low) / ((dx.high - dx.low) or 1.0) * w
        if dy is None:
            return px, oy + h / 2.0
        vy = x.get(dy.label)
        if not isinstance(vy, list) or len(vy) <= dy.index:
            return None
        return px, oy + (dy.high - vy[dy.index]) / ((dy.high - dy.low) or 1.0) * h

    marks: list[str] = []
    for x, feasible in observed:
        if any(x.get(lab) != choice for lab, choice in panel.items()):
            continue
        spot = at(x)
        if spot is None:
            continue
        px, py = spot
        near = closeness(space, x, held, shown, with_choices=False)
        fade = f'data-closeness="{near:.2f}" opacity="{opacity(near):.2f}"'
        if feasible:
            marks.append(
                f'<circle class="cp-observed" data-feasible="1" {fade} cx="{px:.1f}" '
                f'cy="{py:.1f}" r="3.2" fill="#ffffff" stroke="#111827" stroke-width="1.2"/>'
            )
        else:
            cross = _cross(px, py, 3.2)
            marks.append(
                f'<g class="cp-observed" data-feasible="0" {fade}><path d="{cross}" '
                f'stroke="#ffffff" stroke-width="3.2"/><path d="{cross}" stroke="#111827" '
                'stroke-width="1.6"/></g>'
            )
    if held.point_id is not None and all(held.choices.get(k) == v for k, v in panel.items()):
        spot = at({**held.values, **held.choices})
        if spot is not None:
            marks.append(
                f'<circle class="cp-held" data-point-id="{held.point_id}" cx="{spot[0]:.1f}" '
                f'cy="{spot[1]:.1f}" r="7" fill="none" stroke="{HELD_COLOUR}" stroke-width="2.2">'
                f"<title>the held point #{held.point_id}</title></circle>"
            )
    return "".join(marks)


HELD_COLOUR = "#d55e00"  # Okabe-Ito vermillion: apart from cividis' blues and yellows

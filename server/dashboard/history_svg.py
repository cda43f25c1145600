"""The history view: points stored over time and the feasible share, one line per series
(the tasks of a type, or the types of a knowledge base), as SVG.

Two panels over one axis (storage time with idle pauses left out and marked, the points in
storage order, or the runs in the order they started): the cumulative number of points, and
each stretch's feasible share (a marker only where the stretch holds points of that series,
sized by how many, its values on hover). The
colours are Okabe-Ito's, told apart in every common colour-vision deficiency, and each series
also has its own marker shape.
"""

from __future__ import annotations

from html import escape

from server.dashboard.heatmap import FONT
from server.services.browse import History

PALETTE = ("#0072b2", "#e69f00", "#009e73", "#cc79a7", "#56b4e9", "#d55e00", "#000000")
SHAPES = ("circle", "square", "diamond", "triangle", "circle", "square", "diamond")
_W = 520.0
_H = 120.0
_PAD_L = 48.0
_PAD_T = 22.0
_GAP = 46.0
_INK = "#111827"
_MUTED = "#6b7280"


def _marker(shape: str, x: float, y: float, r: float, colour: str) -> str:
    if shape == "circle":
        return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r:.1f}" fill="{colour}"/>'
    if shape == "square":
        return (
            f'<rect x="{x - r:.1f}" y="{y - r:.1f}" width="{2 * r:.1f}" height="{2 * r:.1f}" '
            f'fill="{colour}"/>'
        )
    if shape == "diamond":
        pts = f"{x:.1f},{y - r:.1f} {x + r:.1f},{y:.1f} {x:.1f},{y + r:.1f} {x - r:.1f},{y:.1f}"
    else:
        pts = f"{x:.1f},{y - r:.1f} {x + r:.1f},{y + r:.1f} {x - r:.1f},{y + r:.1f}"
    return f'<polygon points="{pts}" fill="{colour}"/>'


NARROW_W = 290.0  # the plot's width on a phone (one column): its text stays full size


def render_history_svg(history: History, what: str, narrow: bool = False) -> str:
    """`what` names the series in the legend ("task", "type"); `narrow` draws it for a phone,
    with a narrower plot and one legend entry a row."""
    plot_w = NARROW_W if narrow else _W
    per_row = 1 if narrow else 3
    legend_rows = max(1, (len(history.series) + per_row - 1) // per_row)
    width = _PAD_L + plot_w + 16
    top2 = _PAD_T + _H + _GAP
    height = top2 + _H + 30 + 16 * legend_rows + (13 if narrow else 0)
    out = [
        f'<svg class="cp-history" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="points and feasible share per {escape(what)}" '
        f'font-family="{FONT}">'
    ]
    if not history.buckets:
        out.append(f'<text x="10" y="30" font-size="12" fill="{_MUTED}">no points yet</text></svg>')
        return "".join(out)
    buckets = history.buckets
    n = len(buckets)
    cumulative: dict[str, list[int]] = {name: [] for name in history.series}
    for name in history.series:
        total = 0
        for b in buckets:
            total += b.n[name]
            cumulative[name].append(total)
    peak = max(max(v) for v in cumulative.values()) or 1
    step = plot_w / n

    def x_at(k: float) -> float:
        return _PAD_L + step * (k + 0.5)

    out.append(_axes(_PAD_T, "points so far", str(peak), "0", plot_w))
    out.append(_axes(top2, "feasible share", "100%", "0%", plot_w))
    for i, name in enumerate(history.series):
        colour, shape = PALETTE[i % len(PALETTE)], SHAPES[i % len(SHAPES)]
        pts = " ".join(
            f"{x_at(k):.1f},{_PAD_T + _H * (1 - c / peak):.1f}"
            for k, c in enumerate(cumulative[name])
        )
        out.append(
            f'<g class="cp-history-series" data-series="{escape(name)}" '
            f'data-total="{history.totals.get(name, 0)}">'
            f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="1.8"/>'
        )
        for k, b in enumerate(buckets):
            if b.n[name]:
                share = b.n_feasible[name] / b.n[name]
                r = 2.0 + min(3.0, b.n[name] ** 0.5 / 2)
                tip = (
                    f"{what} {name}, {b.label}: {b.n[name]} points, {b.n_feasible[name]} "
                    f"feasible ({share:.0%}); {cumulative[name][k]} so far"
                )
                out.append(
                    f'<g class="cp-history-mark" data-n="{b.n[name]}">'
                    + _marker(shape, x_at(k), top2 + _H * (1 - share), r, colour)
                    + f"<title>{escape(tip)}</title></g>"
                )
        out.append("</g>")
    for k, idle_s in history.gaps:
        gx = _PAD_L + step * k
        out.append(
            f'<g class="cp-history-gap"><line x1="{gx:.1f}" y1="{_PAD_T}" x2="{gx:.1f}" '
            f'y2="{top2 + _H}" stroke="{_MUTED}" stroke-width="1" stroke-dasharray="2 3"/>'
            f'<rect x="{gx - 3:.1f}" y="{_PAD_T}" width="6" height="{top2 + _H - _PAD_T}" '
            f'fill="transparent"><title>idle {_duration(idle_s)}, left out of the axis'
            "</title></rect></g>"
        )
    first, last = _ends(history)
    # Narrow: the two ends on two lines, each from the left.
    last_x, last_dy, anchor = (_PAD_L, 13, "start") if narrow else (_PAD_L + plot_w, 0, "end")
    out.append(
        f'<text class="cp-history-axis" x="{_PAD_L:.0f}" y="{top2 + _H + 14:.0f}" '
        f'font-size="10" fill="{_MUTED}">{escape(first)}</text>'
        f'<text x="{last_x:.0f}" y="{top2 + _H + 14 + last_dy:.0f}" font-size="10" '
        f'text-anchor="{anchor}" fill="{_MUTED}">{escape(last)}</text>'
    )
    legend_top = top2 + _H + 34 + (13 if narrow else 0)
    for i, name in enumerate(history.series):
        x = _PAD_L + (i % per_row) * (plot_w / per_row)
        y = legend_top + 16 * (i // per_row)
        label = f"{what} {name} ({history.totals.get(name, 0)})"
        room = int(plot_w / per_row / 6.2) - 2
        label = label if len(label) <= room else label[: room - 1] + "…"
        out.append(
            _marker(SHAPES[i % len(SHAPES)], x + 4, y - 4, 4, PALETTE[i % len(PALETTE)])
            + f'<text x="{x + 12:.1f}" y="{y:.1f}" font-size="11" fill="{_INK}">'
            f"{escape(label)}</text>"
        )
    out.append("</svg>")
    return "".join(out)


def _axes(top: float, title: str, high: str, low: str, plot_w: float) -> str:
    return (
        f'<rect x="{_PAD_L}" y="{top}" width="{plot_w}" height="{_H}" fill="none" '
        f'stroke="{_MUTED}" stroke-width="0.8"/>'
        f'<text x="{_PAD_L}" y="{top - 6}" font-size="11" fill="{_INK}">{escape(title)}</text>'
        f'<text x="{_PAD_L - 4}" y="{top + 9}" font-size="10" text-anchor="end" '
        f'fill="{_MUTED}">{escape(high)}</text>'
        f'<text x="{_PAD_L - 4}" y="{top + _H}" font-size="10" text-anchor="end" '
        f'fill="{_MUTED}">{escape(low)}</text>'
    )


AXIS_NAMES = {"time": "time", "point": "points in storage order", "run": "runs in start order"}


def _ends(history: History) -> tuple[str, str]:
    """What the axis's two ends say: times (idle stretches left out, counted), or the first
    and last bucket's names."""
    buckets = history.buckets
    if history.axis != "time":
        return buckets[0].label, f"{buckets[-1].label} ({AXIS_NAMES[history.axis]})"
    start, end = buckets[0].start, buckets[-1].end
    clock = "%H:%M:%S" if (end - start).total_seconds() < 3600 else "%H:%M"
    end_format = clock if end.date() == start.date() else "%Y-%m-%d " + clock
    left_out = ""
    if history.gaps:
        idle = sum(s for _, s in history.gaps)
        left_out = f", idle {_duration(idle)} left out"
    return start.strftime("%Y-%m-%d " + clock), f"{end.strftime(end_format)} UTC{left_out}"


def _duration(seconds: float) -> str:
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.0f} s"

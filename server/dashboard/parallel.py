"""Parallel coordinates of a CP type's stored points: an upright axis per decision dimension
(each continuous component, each categorical decision), most relevant first, and a line per
point across them, coloured by its label, as optuna-dashboard draws a study's trials. Lines
are drawn faint, the infeasible ones first, so that the feasible corridor stands out."""

from __future__ import annotations

import math
from collections.abc import Sequence
from html import escape

from contract.models import CategoricalDomain, ContinuousDomain
from server.dashboard.heatmap import FONT, Value, continuous_dims

_H = 180.0
_PAD_T = 34.0
_PAD_B = 40.0
_PAD_X = 46.0
SPACING = 96.0  # between axes, where the width allows
MIN_SPACING = 58.0
FEASIBLE = "#0072b2"  # Okabe-Ito blue
INFEASIBLE = "#d55e00"  # Okabe-Ito vermillion: apart from blue in every common deficiency
_INK = "#111827"
_MUTED = "#6b7280"


Axis = tuple[str, str, int, float, float, list[str]]  # name, label, index, low, high, choices


def _axes(
    space: dict[str, CategoricalDomain | ContinuousDomain], relevance: dict[str, float]
) -> list[Axis]:
    """(name, label, index, low, high, choices) per axis; continuous ones by relevance."""
    dims = sorted(continuous_dims(space), key=lambda d: relevance.get(d.name, math.inf))
    axes: list[Axis] = [(d.name, d.label, d.index, d.low, d.high, []) for d in dims]
    for label, domain in space.items():
        if isinstance(domain, CategoricalDomain):
            axes.append((label, label, -1, 0.0, 1.0, list(domain.choices)))
    return axes


def render_parallel_svg(
    space: dict[str, CategoricalDomain | ContinuousDomain],
    observed: Sequence[tuple[dict[str, Value], bool]],
    relevance: dict[str, float],
    fit_axes: int | None = None,
) -> str:
    """`fit_axes`: how many axes the page's width holds at the usual spacing; more axes than
    that are drawn closer (down to MIN_SPACING) so that they fit without shrinking the text."""
    axes = _axes(space, relevance)
    n = len(axes)
    spacing = SPACING
    if fit_axes is not None and n > fit_axes > 0:
        spacing = max(MIN_SPACING, SPACING * fit_axes / n)
    width = 2 * _PAD_X + spacing * max(n - 1, 1)
    height = _PAD_T + _H + _PAD_B
    out = [
        f'<svg class="cp-parallel" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="parallel coordinates of the stored points" font-family="{FONT}">'
    ]
    if not axes or not observed:
        note = "no points yet" if axes else "no decisions to draw"
        out.append(f'<text x="10" y="30" font-size="12" fill="{_MUTED}">{note}</text></svg>')
        return "".join(out)

    def y_of(axis: Axis, x: dict[str, Value]) -> float:
        _, label, index, low, high, choices = axis
        value = x.get(label)
        if choices:
            k = choices.index(value) if value in choices else 0
            share = 0.5 if len(choices) == 1 else k / (len(choices) - 1)
        else:
            v = float(value[index]) if isinstance(value, list) and len(value) > index else low
            share = (v - low) / ((high - low) or 1.0)
        return _PAD_T + _H * (1.0 - min(max(share, 0.0), 1.0))

    alpha = max(0.08, min(0.6, 12.0 / math.sqrt(len(observed))))
    ordered = sorted(observed, key=lambda pair: pair[1])  # infeasible first, feasible on top
    for x, feasible in ordered:
        pts = " ".join(
            f"{_PAD_X + spacing * k:.1f},{y_of(axis, x):.1f}" for k, axis in enumerate(axes)
        )
        colour = FEASIBLE if feasible else INFEASIBLE
        out.append(
            f'<polyline class="cp-parallel-line" data-feasible="{int(feasible)}" '
            f'points="{pts}" fill="none" stroke="{colour}" stroke-opacity="{alpha:.2f}" '
            'stroke-width="1.2"/>'
        )
    for k, (name, _, _, low, high, choices) in enumerate(axes):
        ax = _PAD_X + spacing * k
        out.append(
            f'<g class="cp-parallel-axis" data-dim="{escape(name)}">'
            f'<line x1="{ax:.1f}" y1="{_PAD_T}" x2="{ax:.1f}" y2="{_PAD_T + _H}" '
            f'stroke="{_MUTED}" stroke-width="1"/>'
            f'<text x="{ax:.1f}" y="{_PAD_T - 18}" font-size="11" text-anchor="middle" '
            f'fill="{_INK}">{escape(_fit(name, spacing))}<title>{escape(name)}</title></text>'
        )
        if choices:
            for j, choice in enumerate(choices):
                share = 0.5 if len(choices) == 1 else j / (len(choices) - 1)
                cy = _PAD_T + _H * (1 - share)
                out.append(
                    f'<text x="{ax + 4:.1f}" y="{cy + 3:.1f}" font-size="9" '
                    f'fill="{_MUTED}">{escape(_fit(choice, spacing - 8))}</text>'
                )
        else:
            out.append(
                f'<text x="{ax:.1f}" y="{_PAD_T - 5}" font-size="9" text-anchor="middle" '
                f'fill="{_MUTED}">{high:.3g}</text>'
                f'<text x="{ax:.1f}" y="{_PAD_T + _H + 12}" font-size="9" '
                f'text-anchor="middle" fill="{_MUTED}">{low:.3g}</text>'
            )
        out.append("</g>")
    n_ok = sum(ok for _, ok in observed)
    out.append(
        f'<g class="cp-parallel-legend" font-size="11" fill="{_INK}">'
        f'<line x1="10" y1="{height - 12}" x2="30" y2="{height - 12}" stroke="{FEASIBLE}" '
        f'stroke-width="2"/><text x="34" y="{height - 8}">feasible ({n_ok})</text>'
        f'<line x1="130" y1="{height - 12}" x2="150" y2="{height - 12}" stroke="{INFEASIBLE}" '
        f'stroke-width="2"/><text x="154" y="{height - 8}">infeasible '
        f"({len(observed) - n_ok})</text></g></svg>"
    )
    return "".join(out)


def _fit(text: str, width: float) -> str:
    """`text` cut to what `width` px hold at about 6 px a character (the title holds it whole)."""
    room = max(3, int(width / 6.2))
    return text if len(text) <= room else text[: room - 1] + "…"

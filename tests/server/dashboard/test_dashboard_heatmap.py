"""The feasibility picture: the grid it asks the surrogate about, and what it draws."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
from pydantic import TypeAdapter

from contract.models import Domain
from server.dashboard.heatmap import (
    HATCH_ID,
    NO_MODEL_COLOUR,
    UNSURE_SD,
    _colour,
    choose_slice,
    continuous_dims,
    grid_points,
    panels_of,
    render_heatmap_svg,
)

SVG_NS = "{http://www.w3.org/2000/svg}"
SPACE = TypeAdapter(dict[str, Domain]).validate_python(
    {
        "#dir": {"kind": "categorical", "choices": ["front", "top"]},
        "#pose": {"kind": "continuous", "low": [0.0, 0.0, -3.0], "high": [1.0, 2.0, 3.0]},
    }
)


def _marks(element: ET.Element) -> list[ET.Element]:
    return [e for e in element.iter() if e.get("class") == "cp-observed"]


def _right_half_feasible(xs: list[dict]) -> list[float]:
    """A stand-in surrogate with a known answer: feasible where #pose[0] > 0.5, top only."""
    return [(1.0 if x["#pose"][0] > 0.5 else 0.0) if x["#dir"] == "top" else 0.25 for x in xs]


def test_dimensions_and_panels_come_from_the_space() -> None:
    dims = continuous_dims(SPACE)
    assert [d.name for d in dims] == ["#pose[0]", "#pose[1]", "#pose[2]"]
    assert (dims[1].low, dims[1].high) == (0.0, 2.0)
    assert panels_of(SPACE) == [{"#dir": "front"}, {"#dir": "top"}]


def test_grid_spans_the_chosen_dimensions_and_holds_the_rest_at_mid_range() -> None:
    dx, _, dz = continuous_dims(SPACE)
    pts = grid_points(SPACE, dx, dz, {"#dir": "top"}, 4)
    assert len(pts) == 16
    assert {p["#dir"] for p in pts} == {"top"}
    assert {p["#pose"][1] for p in pts} == {1.0}  # #pose[1] held at its middle
    xs = sorted({p["#pose"][0] for p in pts})
    assert xs == [0.125, 0.375, 0.625, 0.875]
    # rows go from high y to low y, so that the picture reads like a plot
    assert pts[0]["#pose"][2] > pts[-1]["#pose"][2]


def test_cells_are_coloured_by_the_prediction_and_points_are_marked() -> None:
    dx, dy, _ = continuous_dims(SPACE)
    observed = [
        ({"#dir": "top", "#pose": [0.9, 1.0, 0.0]}, True),
        ({"#dir": "front", "#pose": [0.1, 0.5, 0.0]}, False),
        ({"#dir": "front", "#pose": [0.2, 0.7, 0.0]}, False),
    ]
    svg = render_heatmap_svg(SPACE, dx, dy, _right_half_feasible, observed, n=10)
    root = ET.fromstring(svg)
    panels = {g.get("data-panel"): g for g in root.iter(f"{SVG_NS}g") if g.get("data-panel")}
    assert set(panels) == {"#dir=front", "#dir=top"}
    top_cells = [
        r
        for r in panels["#dir=top"].findall(f"{SVG_NS}rect")
        if r.find(f"{SVG_NS}title") is not None
    ]
    assert len(top_cells) == 100
    middle = min(float(r.get("x")) for r in top_cells) + 90.0  # panels are 180 px wide
    left = {r.get("fill") for r in top_cells if float(r.get("x")) < middle}
    right = {r.get("fill") for r in top_cells if float(r.get("x")) >= middle}
    assert len(left) == 1 and len(right) == 1 and left != right
    assert [m.get("data-feasible") for m in _marks(panels["#dir=top"])] == ["1"]
    assert [m.get("data-feasible") for m in _marks(panels["#dir=front"])] == ["0", "0"]
    assert panels["#dir=top"].get("data-n-points") == "1"


def test_without_a_surrogate_the_cells_are_grey_and_the_points_still_show() -> None:
    dx, dy, _ = continuous_dims(SPACE)
    observed = [({"#dir": "top", "#pose": [0.9, 1.0, 0.0]}, True)]
    root = ET.fromstring(render_heatmap_svg(SPACE, dx, dy, None, observed, n=6))
    cells = [r for r in root.iter(f"{SVG_NS}rect") if r.find(f"{SVG_NS}title") is not None]
    assert {r.get("fill") for r in cells} == {NO_MODEL_COLOUR}
    assert {r.find(f"{SVG_NS}title").text for r in cells} == {"no surrogate yet"}
    assert len(_marks(root)) == 1


def test_a_space_without_continuous_dimensions_gets_one_cell_per_choice() -> None:
    space = TypeAdapter(dict[str, Domain]).validate_python(
        {"#dir": {"kind": "categorical", "choices": ["a", "b", "c"]}}
    )
    calls: list[int] = []

    def predict(xs: list[dict]) -> list[float]:
        calls.append(len(xs))
        return [0.1 * (i + 1) for i in range(len(xs))]

    root = ET.fromstring(render_heatmap_svg(space, None, None, predict))
    assert calls == [3]
    titles = [t.text for t in root.iter(f"{SVG_NS}title")]
    assert titles == ["p=0.10", "p=0.20", "p=0.30"]
    assert not math.isnan(float(titles[0][2:]))


def test_every_panel_is_drawn_and_panels_without_points_say_so() -> None:
    space = TypeAdapter(dict[str, Domain]).validate_python(
        {
            "#a": {"kind": "categorical", "choices": ["p", "q", "r", "s"]},
            "#b": {"kind": "categorical", "choices": ["u", "v", "w", "z"]},
        }
    )
    observed = [({"#a": "p", "#b": "u"}, True), ({"#a": "p", "#b": "u"}, False)]
    root = ET.fromstring(render_heatmap_svg(space, None, None, None, observed))
    panels = [g for g in root.iter(f"{SVG_NS}g") if g.get("data-panel")]
    assert len(panels) == 16  # more than the 12 once drawn silently
    counts = [t.text for t in root.iter(f"{SVG_NS}text") if t.get("class") == "cp-counts"]
    assert counts[0] == "1 ✓ · 1 ✗" and counts[1] == "0 ✓ · 0 ✗"
    assert panels[0].get("opacity") is None and panels[1].get("opacity") is not None
    assert "no data" in "".join(panels[1].itertext())


def test_the_slice_goes_through_the_newest_feasible_point_and_is_named() -> None:
    observed = [
        ({"#dir": "top", "#pose": [0.1, 0.2, 0.3]}, True),
        ({"#dir": "front", "#pose": [0.4, 0.5, 0.6]}, True),
        ({"#dir": "top", "#pose": [0.9, 0.9, 0.9]}, False),
    ]
    held = choose_slice(SPACE, observed, [11, 12, 13])
    assert held.values == {"#pose": [0.4, 0.5, 0.6]} and held.choices == {"#dir": "front"}
    assert held.point_id == 12 and held.origin == "point #12, the newest feasible point"
    infeasible_only = choose_slice(SPACE, [(x, False) for x, _ in observed], [11, 12, 13])
    assert infeasible_only.point_id == 13 and "newest point" in infeasible_only.origin
    assert choose_slice(SPACE, []).values == {"#pose": [0.5, 1.0, 0.0]}
    dx, dy, _ = continuous_dims(SPACE)
    pts = grid_points(SPACE, dx, dy, {"#dir": "top"}, 3, held.values)
    assert {p["#pose"][2] for p in pts} == {0.6}
    svg = render_heatmap_svg(SPACE, dx, dy, None, observed, n=4, held=held)
    assert "held at point #12, the newest feasible point (ringed" in svg


def test_points_fade_with_their_distance_from_the_held_point_off_the_axes() -> None:
    observed = [
        ({"#dir": "top", "#pose": [0.2, 0.2, 0.0]}, True),  # on the slice
        ({"#dir": "top", "#pose": [0.8, 1.0, 0.3]}, True),  # near it in #pose[2]
        ({"#dir": "top", "#pose": [0.5, 0.5, 2.9]}, False),  # far from it in #pose[2]
    ]
    held = choose_slice(SPACE, observed[:1], [5])
    dx, dy, _ = continuous_dims(SPACE)
    root = ET.fromstring(render_heatmap_svg(SPACE, dx, dy, None, observed, n=4, held=held))
    near = [float(m.get("data-closeness")) for m in _marks(root)]
    assert near[0] == 1.0 and 0.5 < near[1] < 1.0 and near[2] < 0.1
    opacities = [float(m.get("opacity")) for m in _marks(root)]
    assert opacities[0] == 1.0 and opacities[2] < 0.2
    rings = [e for e in root.iter() if e.get("class") == "cp-held"]
    assert [r.get("data-point-id") for r in rings] == ["5"]  # in the panel of its own choice


def test_the_scale_is_not_red_to_green() -> None:
    low, high = _colour(0.0), _colour(1.0)
    red_low = int(low[1:3], 16) > int(low[5:7], 16)  # RdYlGn starts red
    green_high = int(high[3:5], 16) > max(int(high[1:3], 16), int(high[5:7], 16)) + 40
    assert not red_low and not green_high


def test_cells_far_from_every_point_are_marked_unsure_and_cells_among_them_are_not() -> None:
    """A real gpytorch fit of a type whose points all lie in one corner of one choice."""
    from surrogate.domains import space_from_json
    from surrogate.encoding import SpaceEncoder
    from surrogate.sources import InMemoryModels

    raw = {
        "#dir": {"kind": "categorical", "choices": ["front", "top"]},
        "#pose": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
    }
    space = TypeAdapter(dict[str, Domain]).validate_python(raw)
    rng = np.random.default_rng(1)
    observed = []
    for _ in range(40):
        pose = (rng.random(2) * 0.4).tolist()
        observed.append(({"#dir": "top", "#pose": pose}, pose[0] > 0.2))
    models = InMemoryModels()
    models.add("corner", space_from_json(raw), observed)
    model = models.model("corner")
    encoder = SpaceEncoder(model.space)

    def judge(xs: list[dict]) -> tuple[list[float], list[float]]:
        z = encoder.encode_points(xs)
        return model.predictor.proba(z).tolist(), model.predictor.uncertainty(z).tolist()

    dx, dy = continuous_dims(space)
    held = choose_slice(space, observed)
    root = ET.fromstring(
        render_heatmap_svg(space, dx, dy, None, observed, n=10, held=held, judge=judge)
    )
    panels = {g.get("data-panel"): g for g in root.iter(f"{SVG_NS}g") if g.get("data-panel")}

    def cells(panel: str) -> list[tuple[float, float, ET.Element]]:
        """(#pose[0], #pose[1], rect) of a panel's cells, read back from the grid."""
        rects = [r for r in panels[panel].iter(f"{SVG_NS}rect") if r.get("class") == "cp-cell"]
        x0, y0 = min(float(r.get("x")) for r in rects), min(float(r.get("y")) for r in rects)
        return [
            (
                (float(r.get("x")) - x0) / 180 + 0.05,
                1 - ((float(r.get("y")) - y0) / 180 + 0.05),
                r,
            )
            for r in rects
        ]

    top = cells("#dir=top")
    far = [r for px, _, r in top if px > 0.6]
    among = [r for px, py, r in top if px < 0.35 and py < 0.35]
    assert far and among
    assert all(r.get("data-unsure") == "1" for r in far)
    assert not any(r.get("data-unsure") for r in among)
    sds = [float(r.find(f"{SVG_NS}title").text.split("sd ")[1]) for r in among]
    assert max(sds) < UNSURE_SD
    assert far[0].find(f"{SVG_NS}title").text.endswith(": unsure")
    # No point holds #dir=front: the stated prior answers there, unsure everywhere.
    assert all(r.get("data-unsure") == "1" for _, _, r in cells("#dir=front"))
    # The hatch covers the unsure cells (a run of them per row) and lets the pointer through.
    hatches = [r for r in panels["#dir=top"].iter(f"{SVG_NS}rect") if r.get("class") == "cp-unsure"]
    covered = sum(round(float(r.get("width")) / 18) for r in hatches)
    assert covered == sum(1 for _, _, r in top if r.get("data-unsure"))
    assert {r.get("pointer-events") for r in hatches} == {"none"}
    assert {r.get("fill") for r in hatches} == {f"url(#{HATCH_ID})"}
    assert root.find(f".//{SVG_NS}pattern[@id='{HATCH_ID}']") is not None
    legend = [g for g in root.iter(f"{SVG_NS}g") if g.get("class") == "cp-legend-unsure"]
    assert len(legend) == 1 and "unsure" in "".join(legend[0].itertext())


def test_without_an_uncertainty_nothing_is_hatched() -> None:
    dx, dy, _ = continuous_dims(SPACE)
    svg = render_heatmap_svg(SPACE, dx, dy, _right_half_feasible, [], n=4)
    assert "cp-unsure" not in svg and HATCH_ID not in svg and "sd " not in svg

"""The causal graph's SVG: every vertex drawn, laid out left to right along the edges by
Graphviz's dot (plain layers without it), no edge through a vertex, no label over a name."""

from __future__ import annotations

import re
import shutil
import xml.etree.ElementTree as ET

import pytest

from contract.models import Graph
from server.dashboard.graph_svg import FALLBACK_NOTE, Box, Layout, label_width, layout, render_svg
from tests.service_support import make_graph

needs_dot = pytest.mark.skipif(
    shutil.which("dot") is None, reason="Graphviz's dot is not installed (.ci/run installs it)"
)

SVG_NS = "{http://www.w3.org/2000/svg}"


def _chain_graph() -> Graph:
    return Graph.model_validate(
        {
            "nodes": [
                {"id": "f", "role": "failure", "label": "Move-Place"},
                {
                    "id": "d",
                    "role": "decision",
                    "label": "#dir",
                    "domain": {"kind": "categorical", "choices": ["top", "front"]},
                },
                {"id": "c", "role": "connection", "label": "Sample-grasp"},
                {"id": "o", "role": "context", "label": "shelf <top> & co"},
            ],
            "edges": [
                {"source": "d", "target": "c", "label": "out"},
                {"source": "c", "target": "f", "label": "grasp"},
                {"source": "o", "target": "f", "label": "collides"},
            ],
        }
    )


def _apart(a: Box, b: Box) -> bool:
    return abs(a.x - b.x) >= (a.w + b.w) / 2 or abs(a.y - b.y) >= (a.h + b.h) / 2


def _samples(path: str) -> list[tuple[float, float]]:
    """Points along an `M .. C .. L ..` path: 20 per cubic piece, the ends of lines."""
    out: list[tuple[float, float]] = []
    pen = (0.0, 0.0)
    for op, args in re.findall(r"([MCL])([^MCL]*)", path):
        pts = [tuple(map(float, p.split(","))) for p in args.split()]
        if op == "C":
            (ax, ay), (bx, by), (cx, cy) = pts
            for k in range(21):
                t = k / 20
                u = 1 - t
                out.append(
                    (
                        u**3 * pen[0] + 3 * u * u * t * ax + 3 * u * t * t * bx + t**3 * cx,
                        u**3 * pen[1] + 3 * u * u * t * ay + 3 * u * t * t * by + t**3 * cy,
                    )
                )
        else:
            out.append(pts[-1])
        pen = pts[-1]
    return out


def _check_readable(lay: Layout) -> None:
    """No two vertexes overlap, no edge enters a vertex it does not join, and no edge label
    covers a vertex."""
    boxes = lay.boxes
    for a in boxes.values():
        for b in boxes.values():
            assert a is b or _apart(a, b)
    for route in lay.routes:
        for node_id, box in boxes.items():
            if node_id in (route.source, route.target):
                continue
            for px, py in _samples(route.path):
                inside = abs(px - box.x) < box.w / 2 - 1 and abs(py - box.y) < box.h / 2 - 1
                assert not inside, f"{route.source}->{route.target} crosses {node_id}"
            if route.label and route.label_at is not None:
                tag = Box(*route.label_at, label_width(route.label), 12.0)
                assert _apart(tag, box), f"label {route.label!r} covers {node_id}"


@needs_dot
def test_dot_lays_out_along_the_edges_without_crossing_vertexes_or_covering_names() -> None:
    lay = layout(_chain_graph())
    assert lay.engine == "dot"
    boxes = lay.boxes
    assert boxes["d"].x < boxes["c"].x < boxes["f"].x
    assert boxes["o"].x < boxes["f"].x
    _check_readable(lay)


@needs_dot
def test_a_wide_graph_with_edges_skipping_layers_stays_readable() -> None:
    """Edges from every decision both to a connection and straight to the failure: the
    shape straight lines drew through the connection vertexes."""
    nodes = [{"id": "f", "role": "failure", "label": "Plan-motion"}]
    edges = []
    for i in range(4):
        nodes.append({"id": f"d{i}", "role": "decision", "label": f"#pose{i}"})
        nodes.append({"id": f"c{i}", "role": "connection", "label": f"Sample-place-{i}"})
        edges.append({"source": f"d{i}", "target": f"c{i}", "label": "placement"})
        edges.append({"source": f"c{i}", "target": "f", "label": "moves through"})
        edges.append({"source": f"d{i}", "target": "f", "label": "pose"})
    nodes.append({"id": "o", "role": "context", "label": "shelf"})
    edges.append({"source": "o", "target": "f", "label": "collides"})
    _check_readable(layout(Graph.model_validate({"nodes": nodes, "edges": edges})))


def test_without_dot_the_graph_falls_back_to_layers_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("PATH", "/nonexistent")
    lay = layout(_chain_graph())
    assert lay.engine == "layers"
    assert lay.boxes["d"].x < lay.boxes["c"].x < lay.boxes["f"].x
    svg = render_svg(_chain_graph())
    assert FALLBACK_NOTE in svg
    ET.fromstring(svg)


def test_svg_is_well_formed_with_one_group_per_vertex_and_escaped_text() -> None:
    svg = render_svg(_chain_graph())
    root = ET.fromstring(svg)
    groups = root.findall(f"{SVG_NS}g")
    assert sorted(g.get("data-role") for g in groups) == [
        "connection",
        "context",
        "decision",
        "failure",
    ]
    texts = [t.text for t in root.iter(f"{SVG_NS}text")]
    assert "shelf <top> & co" in texts
    assert "2 choices" in texts
    assert len(root.findall(f"{SVG_NS}path[@class='cp-edge']")) == 3
    assert "sans-serif" in (root.get("font-family") or "")
    assert root.get("viewBox", "").startswith("0 0 ")


def test_a_graph_with_a_cycle_is_laid_out(monkeypatch: pytest.MonkeyPatch) -> None:
    graph = Graph.model_validate(
        {
            "nodes": [
                {"id": "f", "role": "failure", "label": "Inv-kin"},
                {"id": "a", "role": "connection", "label": "a"},
                {"id": "b", "role": "connection", "label": "b"},
                {
                    "id": "d",
                    "role": "decision",
                    "label": "#pose",
                    "domain": {"kind": "continuous", "low": [0, 0], "high": [1, 1]},
                },
            ],
            "edges": [
                {"source": "a", "target": "b"},
                {"source": "b", "target": "a"},
                {"source": "d", "target": "a"},
                {"source": "b", "target": "f"},
            ],
        }
    )
    if shutil.which("dot") is not None:
        lay = layout(graph)
        assert lay.boxes["d"].x < lay.boxes["f"].x
        _check_readable(lay)
    monkeypatch.setenv("PATH", "/nonexistent")  # plain layers: by role
    boxes = layout(graph).boxes
    assert boxes["d"].x < boxes["a"].x == boxes["b"].x < boxes["f"].x
    ET.fromstring(render_svg(graph))


def test_the_service_test_graph_renders() -> None:
    svg = render_svg(Graph.model_validate(make_graph(context=("box1", "box2"))))
    assert svg.count('class="cp-node"') == 5

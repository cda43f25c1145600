"""The causal graph's SVG: every vertex drawn, laid out left to right along the edges."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from client.models import Graph
from server.dashboard.graph_svg import layout, render_svg
from tests.service_support import make_graph

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


def test_layers_follow_the_edges_from_decisions_to_the_failure() -> None:
    boxes = layout(_chain_graph())
    assert boxes["d"].x < boxes["c"].x < boxes["f"].x
    assert boxes["o"].x < boxes["f"].x
    for a in boxes.values():  # no two vertexes overlap
        for b in boxes.values():
            if a is not b:
                apart_x = abs(a.x - b.x) >= (a.w + b.w) / 2
                apart_y = abs(a.y - b.y) >= (a.h + b.h) / 2
                assert apart_x or apart_y


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
    assert len(root.findall(f"{SVG_NS}line")) == 3


def test_a_graph_with_a_cycle_is_laid_out_by_role() -> None:
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
    boxes = layout(graph)
    assert boxes["d"].x < boxes["a"].x == boxes["b"].x < boxes["f"].x
    ET.fromstring(render_svg(graph))


def test_the_service_test_graph_renders() -> None:
    svg = render_svg(Graph.model_validate(make_graph(context=("box1", "box2"))))
    assert svg.count('class="cp-node"') == 5

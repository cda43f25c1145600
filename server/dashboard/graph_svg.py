"""A CP type's causal graph drawn as inline SVG, laid out on the server.

Layout: layered left to right along the edges (networkx topological generations), so that the
decision vertexes stand on the left and the failure vertex on the right; within a layer the
vertexes are ordered by the mean height of their predecessors to keep crossings few. A graph
with a cycle falls back to layers by role.
"""

from __future__ import annotations

from dataclasses import dataclass
from html import escape

import networkx as nx

from client.models import CategoricalDomain, Graph, Node

ROLE_COLOURS = {
    "decision": "#2563eb",
    "context": "#6b7280",
    "connection": "#d97706",
    "failure": "#dc2626",
}
_ROLE_LAYER = {"decision": 0, "context": 0, "connection": 1, "failure": 2}
_CHAR_W = 7.2  # px per character at the 12 px font used below
_NODE_H = 40.0
_GAP_X = 70.0
_GAP_Y = 22.0
_MARGIN = 16.0


@dataclass(frozen=True)
class Box:
    """A laid-out vertex: centre (x, y) and size in SVG pixels."""

    x: float
    y: float
    w: float
    h: float


def _domain_note(node: Node) -> str:
    if node.domain is None:
        return ""
    if isinstance(node.domain, CategoricalDomain):
        return f"{len(node.domain.choices)} choices"
    return f"box, {len(node.domain.low)}-d"


def _layers(g: nx.DiGraph, nodes: dict[str, Node]) -> list[list[str]]:
    if nx.is_directed_acyclic_graph(g):
        return [
            sorted(gen, key=lambda n: (nodes[n].role, nodes[n].label))
            for gen in nx.topological_generations(g)
        ]
    by_role: dict[int, list[str]] = {}
    for node_id, node in nodes.items():
        by_role.setdefault(_ROLE_LAYER[node.role], []).append(node_id)
    return [
        sorted(by_role[k], key=lambda n: (nodes[n].role, nodes[n].label)) for k in sorted(by_role)
    ]


def layout(graph: Graph) -> dict[str, Box]:
    """Boxes for every vertex, in SVG pixel coordinates with the origin at the top left."""
    nodes = {n.id: n for n in graph.nodes}
    g = nx.DiGraph()
    g.add_nodes_from(nodes)
    g.add_edges_from((e.source, e.target) for e in graph.edges if e.source != e.target)
    layers = _layers(g, nodes)

    def width(node_id: str) -> float:
        node = nodes[node_id]
        text = max(len(node.label), len(_domain_note(node)))
        return max(84.0, text * _CHAR_W + 20.0)

    rank: dict[str, float] = {}
    boxes: dict[str, Box] = {}
    x = _MARGIN
    tallest = max(len(layer) for layer in layers)
    for layer in layers:
        # Barycentre ordering: follow the predecessors' positions (layer 0 keeps its sort).
        def bary(n: str, _layer: list[str] = layer) -> float:
            ranks = [rank[p] for p in g.predecessors(n) if p in rank]
            return sum(ranks) / len(ranks) if ranks else float(_layer.index(n))

        ordered = sorted(layer, key=bary)
        col_w = max(width(n) for n in ordered)
        offset = (tallest - len(ordered)) * (_NODE_H + _GAP_Y) / 2.0
        for i, node_id in enumerate(ordered):
            rank[node_id] = float(i)
            y = _MARGIN + offset + i * (_NODE_H + _GAP_Y) + _NODE_H / 2.0
            boxes[node_id] = Box(x + col_w / 2.0, y, width(node_id), _NODE_H)
        x += col_w + _GAP_X
    return boxes


def _border_point(box: Box, toward: tuple[float, float]) -> tuple[float, float]:
    """Where the segment from the box centre toward a point leaves the box."""
    dx, dy = toward[0] - box.x, toward[1] - box.y
    if dx == 0 and dy == 0:
        return box.x, box.y
    sx = (box.w / 2.0) / abs(dx) if dx else float("inf")
    sy = (box.h / 2.0) / abs(dy) if dy else float("inf")
    s = min(sx, sy)
    return box.x + dx * s, box.y + dy * s


def render_svg(graph: Graph) -> str:
    """The whole graph as one `<svg>` element (no XML prolog), ready to inline in HTML."""
    boxes = layout(graph)
    width = max(b.x + b.w / 2.0 for b in boxes.values()) + _MARGIN
    height = max(b.y + b.h / 2.0 for b in boxes.values()) + _MARGIN
    parts = [
        f'<svg class="cp-graph" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="causal graph">',
        '<defs><marker id="cp-arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" '
        'markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" '
        'fill="#374151"/></marker></defs>',
    ]
    for edge in graph.edges:
        if edge.source == edge.target:
            continue
        a, b = boxes[edge.source], boxes[edge.target]
        x1, y1 = _border_point(a, (b.x, b.y))
        x2, y2 = _border_point(b, (a.x, a.y))
        parts.append(
            f'<line class="cp-edge" x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" '
            'stroke="#374151" stroke-width="1.3" marker-end="url(#cp-arrow)"/>'
        )
        if edge.label:
            parts.append(
                f'<text class="cp-edge-label" x="{(x1 + x2) / 2:.1f}" y="{(y1 + y2) / 2 - 4:.1f}" '
                f'font-size="10" text-anchor="middle" fill="#374151">{escape(edge.label)}</text>'
            )
    for node in graph.nodes:
        box = boxes[node.id]
        colour = ROLE_COLOURS[node.role]
        note = _domain_note(node)
        title = f"{node.role}: {node.label}" + (f" ({note})" if note else "")
        parts.append(
            f'<g class="cp-node" data-role="{node.role}" data-id="{escape(node.id)}">'
            f"<title>{escape(title)}</title>"
            f'<rect x="{box.x - box.w / 2:.1f}" y="{box.y - box.h / 2:.1f}" width="{box.w:.1f}" '
            f'height="{box.h:.1f}" rx="8" fill="{colour}" fill-opacity="0.12" stroke="{colour}" '
            'stroke-width="1.6"/>'
        )
        label_y = box.y - 3 if note else box.y + 4
        parts.append(
            f'<text x="{box.x:.1f}" y="{label_y:.1f}" font-size="12" text-anchor="middle" '
            f'fill="#111827">{escape(node.label)}</text>'
        )
        if note:
            parts.append(
                f'<text x="{box.x:.1f}" y="{box.y + 12:.1f}" font-size="10" '
                f'text-anchor="middle" fill="{colour}">{escape(note)}</text>'
            )
        parts.append("</g>")
    parts.append("</svg>")
    return "".join(parts)

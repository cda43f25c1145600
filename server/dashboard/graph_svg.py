"""A CP type's causal graph drawn as SVG, laid out on the server.

Layout: Graphviz's `dot` (through the `graphviz` package), left to right along the edges, so
that decisions stand on the left and the failure on the right. dot routes every edge as a
spline around the vertexes and places each edge label in a slot of its own, so no edge runs
through a vertex and no label covers a name. Without the `dot` program (Debian's `graphviz`)
the graph falls back to plain layers with straight edges and says so in the picture.
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from html import escape

import graphviz
import networkx as nx

from contract.models import CategoricalDomain, Graph, Node

ROLE_COLOURS = {
    "decision": "#2563eb",
    "context": "#6b7280",
    "connection": "#d97706",
    "failure": "#dc2626",
}
FONT = "system-ui, -apple-system, 'Segoe UI', Helvetica, Arial, sans-serif"
_ROLE_LAYER = {"decision": 0, "context": 0, "connection": 1, "failure": 2}
_CHAR_W = 7.2  # px per character at the 12 px font of a vertex name
_LABEL_CHAR_W = 6.2  # px per character at the 10 px font of an edge label
_NODE_H = 40.0
_GAP_X = 70.0
_GAP_Y = 22.0
_MARGIN = 16.0
_DPI = 72.0  # dot's points per inch: its coordinates are points
ToSvg = Callable[[str], tuple[float, float]]  # dot's "x,y" (y up) -> SVG pixels (y down)
FALLBACK_NOTE = "Graphviz (dot) not found: plain layers, edges may cross vertexes"


@dataclass(frozen=True)
class Box:
    """A laid-out vertex: centre (x, y) and size in SVG pixels."""

    x: float
    y: float
    w: float
    h: float


@dataclass(frozen=True)
class Route:
    """A laid-out edge: an SVG path from source to target and where its label goes."""

    source: str
    target: str
    label: str
    path: str
    label_at: tuple[float, float] | None


@dataclass(frozen=True)
class Layout:
    boxes: dict[str, Box]
    routes: list[Route]
    width: float
    height: float
    engine: str  # "dot" or "layers"


def _domain_note(node: Node) -> str:
    if node.domain is None:
        return ""
    if isinstance(node.domain, CategoricalDomain):
        return f"{len(node.domain.choices)} choices"
    return f"box, {len(node.domain.low)}-d"


def _node_width(node: Node) -> float:
    text = max(len(node.label), len(_domain_note(node)))
    return max(84.0, text * _CHAR_W + 20.0)


def label_width(text: str) -> float:
    """The width an edge label takes at its 10 px font, as the SVG draws it."""
    return len(text) * _LABEL_CHAR_W + 4.0


def _edges(graph: Graph) -> list[tuple[str, str, str]]:
    return [(e.source, e.target, e.label or "") for e in graph.edges if e.source != e.target]


def layout(graph: Graph) -> Layout:
    """dot's layout when the program is there, else plain layers."""
    try:
        return _dot_layout(graph)
    except (graphviz.ExecutableNotFound, subprocess.SubprocessError):
        return _layered_layout(graph)


def _dot_layout(graph: Graph) -> Layout:
    """Vertex sizes are fixed to what the SVG draws; dot places them and routes the edges."""
    names = {node.id: f"n{i}" for i, node in enumerate(graph.nodes)}
    dot = graphviz.Digraph(
        graph_attr={"rankdir": "LR", "nodesep": "0.3", "ranksep": "0.6", "splines": "spline"},
        node_attr={"shape": "box", "fixedsize": "true", "label": ""},
        # Label slots sized a little above the 10 px the SVG draws them at: dot measures with
        # its own font metrics, which need not be the browser's.
        edge_attr={"fontsize": "11", "fontname": "Helvetica"},
    )
    for node in graph.nodes:
        dot.node(
            names[node.id],
            width=f"{_node_width(node) / _DPI:.3f}",
            height=f"{_NODE_H / _DPI:.3f}",
        )
    edges = _edges(graph)
    for source, target, label in edges:
        attrs = {"label": graphviz.escape(label)} if label else {}
        dot.edge(names[source], names[target], **attrs)
    answer = json.loads(dot.pipe(format="json0", engine="dot"))
    _, _, right, top = (float(v) for v in answer["bb"].split(","))

    def point(text: str) -> tuple[float, float]:
        x, y = text.split(",")[-2:]
        return float(x) + _MARGIN, top - float(y) + _MARGIN

    by_name = {obj["name"]: obj for obj in answer["objects"]}
    boxes = {}
    for node in graph.nodes:
        obj = by_name[names[node.id]]
        x, y = point(obj["pos"])
        boxes[node.id] = Box(x, y, float(obj["width"]) * _DPI, float(obj["height"]) * _DPI)
    routes = []
    for (source, target, label), edge in zip(edges, answer.get("edges", []), strict=True):
        routes.append(
            Route(source, target, label, _spline_path(edge["pos"], point), _label_at(edge, point))
        )
    return Layout(boxes, routes, right + 2 * _MARGIN, top + 2 * _MARGIN, "dot")


def _label_at(edge: dict[str, str], point: ToSvg) -> tuple[float, float] | None:
    return point(edge["lp"]) if "lp" in edge else None


def _spline_path(pos: str, point: ToSvg) -> str:
    """dot's `e,x,y p0 p1 ... p3n` (a cubic B-spline in Bezier form, then the arrow tip) as an
    SVG path: M p0 C p1 p2 p3 ... and a last segment to the tip, where the marker goes."""
    tip = None
    controls = []
    for part in pos.split():
        if part.startswith("e,"):
            tip = point(part)
        elif not part.startswith("s,"):
            controls.append(point(part))
    (x0, y0), rest = controls[0], controls[1:]
    d = [f"M{x0:.1f},{y0:.1f}"]
    for k in range(0, len(rest) - len(rest) % 3, 3):
        (ax, ay), (bx, by), (cx, cy) = rest[k : k + 3]
        d.append(f"C{ax:.1f},{ay:.1f} {bx:.1f},{by:.1f} {cx:.1f},{cy:.1f}")
    if tip is not None:
        d.append(f"L{tip[0]:.1f},{tip[1]:.1f}")
    return " ".join(d)


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


def _layered_layout(graph: Graph) -> Layout:
    """Layers along the edges (networkx topological generations), ordered by the mean height
    of their predecessors; straight edges, labels at their middles."""
    nodes = {n.id: n for n in graph.nodes}
    g = nx.DiGraph()
    g.add_nodes_from(nodes)
    edges = _edges(graph)
    g.add_edges_from((s, t) for s, t, _ in edges)
    layers = _layers(g, nodes)
    gap = max([_GAP_X, *(label_width(label) + 16.0 for _, _, label in edges)])
    rank: dict[str, float] = {}
    boxes: dict[str, Box] = {}
    x = _MARGIN
    tallest = max(len(layer) for layer in layers)
    for layer in layers:

        def bary(n: str, _layer: list[str] = layer) -> float:
            ranks = [rank[p] for p in g.predecessors(n) if p in rank]
            return sum(ranks) / len(ranks) if ranks else float(_layer.index(n))

        ordered = sorted(layer, key=bary)
        col_w = max(_node_width(nodes[n]) for n in ordered)
        offset = (tallest - len(ordered)) * (_NODE_H + _GAP_Y) / 2.0
        for i, node_id in enumerate(ordered):
            rank[node_id] = float(i)
            y = _MARGIN + offset + i * (_NODE_H + _GAP_Y) + _NODE_H / 2.0
            boxes[node_id] = Box(x + col_w / 2.0, y, _node_width(nodes[node_id]), _NODE_H)
        x += col_w + gap
    routes = []
    for source, target, label in edges:
        a, b = boxes[source], boxes[target]
        x1, y1 = _border_point(a, (b.x, b.y))
        x2, y2 = _border_point(b, (a.x, a.y))
        mid = ((x1 + x2) / 2.0, (y1 + y2) / 2.0 - 4.0) if label else None
        routes.append(Route(source, target, label, f"M{x1:.1f},{y1:.1f} L{x2:.1f},{y2:.1f}", mid))
    width = max(b.x + b.w / 2.0 for b in boxes.values()) + _MARGIN
    height = max(b.y + b.h / 2.0 for b in boxes.values()) + _MARGIN + 14.0
    return Layout(boxes, routes, width, height, "layers")


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
    """The whole graph as one `<svg>` element (no XML prolog), ready to inline in HTML or to
    serve alone: it scales to its container (viewBox) and names a sans-serif font itself."""
    lay = layout(graph)
    width, height = lay.width, lay.height
    parts = [
        f'<svg class="cp-graph" xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" '
        f'height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" role="img" '
        f'aria-label="causal graph" font-family="{FONT}" data-layout="{lay.engine}">',
        '<defs><marker id="cp-arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" '
        'markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" '
        'fill="#374151"/></marker></defs>',
    ]
    for route in lay.routes:
        parts.append(
            f'<path class="cp-edge" d="{route.path}" fill="none" stroke="#374151" '
            'stroke-width="1.3" marker-end="url(#cp-arrow)"/>'
        )
    for route in lay.routes:
        if route.label and route.label_at is not None:
            x, y = route.label_at
            parts.append(
                f'<text class="cp-edge-label" x="{x:.1f}" y="{y + 3.5:.1f}" font-size="10" '
                f'text-anchor="middle" fill="#374151">{escape(route.label)}</text>'
            )
    for node in graph.nodes:
        parts.append(_node_svg(node, lay.boxes[node.id]))
    if lay.engine != "dot":
        parts.append(
            f'<text class="cp-layout-note" x="{_MARGIN:.0f}" y="{height - 4:.0f}" '
            f'font-size="10" fill="#6b7280">{escape(FALLBACK_NOTE)}</text>'
        )
    parts.append("</svg>")
    return "".join(parts)


def _node_svg(node: Node, box: Box) -> str:
    colour = ROLE_COLOURS[node.role]
    note = _domain_note(node)
    title = f"{node.role}: {node.label}" + (f" ({note})" if note else "")
    label_y = box.y - 3 if note else box.y + 4
    parts = [
        f'<g class="cp-node" data-role="{node.role}" data-id="{escape(node.id)}">'
        f"<title>{escape(title)}</title>"
        f'<rect x="{box.x - box.w / 2:.1f}" y="{box.y - box.h / 2:.1f}" width="{box.w:.1f}" '
        f'height="{box.h:.1f}" rx="8" fill="{colour}" fill-opacity="0.12" stroke="{colour}" '
        'stroke-width="1.6"/>',
        f'<text class="cp-label" x="{box.x:.1f}" y="{label_y:.1f}" font-size="12" '
        f'text-anchor="middle" fill="#111827">{escape(node.label)}</text>',
    ]
    if note:
        parts.append(
            f'<text x="{box.x:.1f}" y="{box.y + 12:.1f}" font-size="10" '
            f'text-anchor="middle" fill="{colour}">{escape(note)}</text>'
        )
    parts.append("</g>")
    return "".join(parts)

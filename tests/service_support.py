"""Helpers for tests of the knowledge-base service: causal graphs and points to post."""

from __future__ import annotations

import uuid
from typing import Any

POSE_DOMAIN = {"kind": "continuous", "low": [0.0, 0.0, -3.0], "high": [1.0, 1.0, 3.0]}
DIR_DOMAIN = {"kind": "categorical", "choices": ["front", "right", "top", "back", "left"]}


def make_graph(
    failure: str = "Inv-kin",
    context: tuple[str, ...] = ("box1",),
    *,
    pose_domain: dict[str, Any] | None = None,
    prefix: str = "",
) -> dict[str, Any]:
    """A small causal graph: #dir and #pose feed the failure, context bodies collide with it.

    `prefix` renames the node ids (the type must not change); `pose_domain` overrides #pose's.
    """
    nodes = [
        {"id": f"{prefix}f", "role": "failure", "label": failure},
        {"id": f"{prefix}d", "role": "decision", "label": "#dir", "domain": DIR_DOMAIN},
        {
            "id": f"{prefix}p",
            "role": "decision",
            "label": "#pose",
            "domain": pose_domain or POSE_DOMAIN,
        },
    ]
    edges = [
        {"source": f"{prefix}d", "target": f"{prefix}f", "label": "grasp"},
        {"source": f"{prefix}p", "target": f"{prefix}f", "label": "pose"},
    ]
    for i, body in enumerate(context):
        nodes.append({"id": f"{prefix}c{i}", "role": "context", "label": body})
        edges.append({"source": f"{prefix}c{i}", "target": f"{prefix}f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


def make_point(
    i: int = 0,
    *,
    graph: dict[str, Any] | None = None,
    key: str | None = "auto",
    feasible: bool | None = None,
    **source: Any,
) -> dict[str, Any]:
    """Point number `i` of `graph` (deterministic x); `key="auto"` gives a fresh unique key."""
    point: dict[str, Any] = {
        "graph": graph or make_graph(),
        "x": {
            "#dir": DIR_DOMAIN["choices"][i % 5],
            "#pose": [(i % 10) / 10, (i % 7) / 7, -3.0 + (i % 13) * 0.5],
        },
        "feasible": (i % 3 == 0) if feasible is None else feasible,
    }
    if key == "auto":
        point["key"] = uuid.uuid4().hex
    elif key is not None:
        point["key"] = key
    if source:
        point["source"] = source
    return point


def collision_pair() -> tuple[dict[str, Any], dict[str, Any]]:
    """A directed 6-cycle and two directed 3-cycles, every cycle node fed by the failure:
    not isomorphic, yet Weisfeiler-Lehman gives every cycle node the same colour in both."""
    domain = {"kind": "categorical", "choices": ["a", "b"]}

    def graph(cycles: list[list[int]]) -> dict[str, Any]:
        nodes = [
            {"id": "f", "role": "failure", "label": "Plan-motion"},
            {"id": "k", "role": "decision", "label": "#k", "domain": domain},
        ]
        edges = [{"source": "k", "target": "f", "label": "feeds"}]
        for cycle in cycles:
            for i, n in enumerate(cycle):
                nodes.append({"id": f"c{n}", "role": "connection", "label": "link"})
                nxt = cycle[(i + 1) % len(cycle)]
                edges.append({"source": f"c{n}", "target": f"c{nxt}", "label": "next"})
                edges.append({"source": "f", "target": f"c{n}", "label": "via"})
        return {"nodes": nodes, "edges": edges}

    return graph([[0, 1, 2, 3, 4, 5]]), graph([[0, 1, 2], [3, 4, 5]])

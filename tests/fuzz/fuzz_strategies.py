"""Hypothesis strategies for wire payloads: valid causal graphs and points, and ways to break them.

Valid graphs follow DESIGN.md section 3: one failure vertex, decision vertexes with unique labels
and a domain each, context vertexes, edges between existing ids. `x_for(graph)` draws a point
that fits the graph's decision domains.
"""

from __future__ import annotations

import math
from typing import Any

from hypothesis import strategies as st

LABEL_ALPHABET = st.characters(min_codepoint=33, max_codepoint=0x2FF, exclude_characters="\\")
labels = st.text(LABEL_ALPHABET, min_size=1, max_size=12)

categorical_domains = st.lists(labels, min_size=1, max_size=5, unique=True).map(
    lambda choices: {"kind": "categorical", "choices": choices}
)


@st.composite
def continuous_domains(draw: st.DrawFn) -> dict[str, Any]:
    dim = draw(st.integers(1, 4))
    low = draw(st.lists(st.floats(-10, 10), min_size=dim, max_size=dim))
    width = draw(st.lists(st.floats(0.01, 10), min_size=dim, max_size=dim))
    high = [lo + w for lo, w in zip(low, width, strict=True)]
    return {"kind": "continuous", "low": low, "high": high}


domains = st.one_of(categorical_domains, continuous_domains())


@st.composite
def graphs(draw: st.DrawFn, max_decisions: int = 3, max_context: int = 2) -> dict[str, Any]:
    failure = draw(st.sampled_from(["Inv-kin", "Plan-motion", "Move-Pick", "Move-Place"]))
    decision_labels = draw(st.lists(labels, min_size=1, max_size=max_decisions, unique=True))
    context_labels = draw(st.lists(labels, max_size=max_context))
    nodes = [{"id": "f", "role": "failure", "label": failure}]
    edges = []
    for i, label in enumerate(decision_labels):
        nodes.append({"id": f"d{i}", "role": "decision", "label": label, "domain": draw(domains)})
        edges.append({"source": f"d{i}", "target": "f", "label": "feeds"})
    for i, label in enumerate(context_labels):
        nodes.append({"id": f"c{i}", "role": "context", "label": label})
        edges.append({"source": f"c{i}", "target": "f", "label": "collides"})
    return {"nodes": nodes, "edges": edges}


def decision_domains(graph: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {n["label"]: n["domain"] for n in graph["nodes"] if n["role"] == "decision"}


def value_in(domain: dict[str, Any]) -> st.SearchStrategy[Any]:
    if domain["kind"] == "categorical":
        return st.sampled_from(domain["choices"])
    return st.tuples(
        *(st.floats(lo, hi) for lo, hi in zip(domain["low"], domain["high"], strict=True))
    ).map(list)


def x_for(graph: dict[str, Any]) -> st.SearchStrategy[dict[str, Any]]:
    return st.fixed_dictionaries({k: value_in(d) for k, d in decision_domains(graph).items()})


@st.composite
def points(draw: st.DrawFn) -> dict[str, Any]:
    graph = draw(graphs())
    return {"graph": graph, "x": draw(x_for(graph)), "feasible": draw(st.booleans())}


CONTINUOUS_BREAKS = [
    "non-finite",
    "too-high",
    "too-low",
    "dim+1",
    "dim-1",
    "string",
    "missing",
    "extra-label",
]
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


@st.composite
def bad_x(draw: st.DrawFn, graph: dict[str, Any]) -> dict[str, Any]:
    """A point value that must be refused: non-finite, out of bounds, wrong dimension,
    unknown choice, missing or unknown label, or a value of the wrong kind."""
    good = draw(x_for(graph))
    spaces = decision_domains(graph)
    label = draw(st.sampled_from(sorted(spaces)))
    domain = spaces[label]
    bad = dict(good)
    if domain["kind"] == "categorical":
        how = draw(st.sampled_from(["unknown-choice", "vector", "missing", "extra-label"]))
        if how == "unknown-choice":
            bad[label] = draw(labels.filter(lambda s: s not in domain["choices"]))
        elif how == "vector":
            bad[label] = [0.5]
    else:
        dim = len(domain["low"])
        how = draw(st.sampled_from(CONTINUOUS_BREAKS))
        vec = list(good[label])
        i = draw(st.integers(0, dim - 1))
        if how == "non-finite":
            vec[i] = draw(NON_FINITE)
        elif how == "too-high":
            vec[i] = domain["high"][i] + draw(st.floats(0.5, 1e6))
        elif how == "too-low":
            vec[i] = domain["low"][i] - draw(st.floats(0.5, 1e6))
        elif how == "dim+1":
            vec.append(domain["low"][0])
        elif how == "dim-1":
            vec = vec[:-1]
        elif how == "string":
            bad[label] = "front"
        if how not in ("string", "missing", "extra-label"):
            bad[label] = vec
    if how == "missing":
        del bad[label]
    elif how == "extra-label":
        bad[draw(labels.filter(lambda s: s not in spaces))] = "front"
    return bad

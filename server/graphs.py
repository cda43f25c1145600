"""Causal graphs -> CP type IDs, and decision values checked against a type's space.

The type ID is networkx's Weisfeiler-Lehman hash of the directed graph with node attribute
`role:label`, each edge subdivided by a node labelled `edge:<label>`: node ids and order do not
matter. (Subdivided, because networkx 3.6 drops the edge direction when `edge_attr` is given:
it prefixes successor and predecessor labels alike with the edge label.) A hash says
"probably the same type"; `check_same_type` then confirms with an isomorphism test (roles,
labels, domains, edge labels) so that a collision or a changed domain is a conflict, never
a silent merge. Resolved graphs are cached by their JSON, because planners post the same
few graphs over and over; the hash is worked out from the per-node hashes that the canonical
order needs (`wl_hashes`), one Weisfeiler-Lehman pass rather than two, as a planner's prematch
sends hundreds of graphs new to the service.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from hashlib import blake2b
from typing import Any

import networkx as nx
from networkx.algorithms.isomorphism import DiGraphMatcher

from contract.models import CategoricalDomain, ContinuousDomain, Graph, Value

Domain = CategoricalDomain | ContinuousDomain
# Each edge is two hops once subdivided: 6 iterations see as far as 3 on the graph itself.
WL_ITERATIONS = 6
# networkx >= 3.5 tells on every call that directed hashes changed in 3.5; we rely on >= 3.5.
warnings.filterwarnings("ignore", message="The hashes produced for directed graphs changed")
ROLE_ORDER = {"failure": 0, "decision": 1, "context": 2, "connection": 3}


class GraphError(ValueError):
    """The graph is not a valid causal graph; the message names the field (relative path)."""


class TypeConflict(Exception):
    """Same hash as a stored type, but not the same type; the message says why."""


@dataclass(frozen=True)
class ResolvedGraph:
    """A validated graph with its type ID, canonical form and decision space."""

    type_id: str
    canonical: dict[str, Any]
    space: dict[str, Domain]
    failure: str
    decisions: list[str]
    context: list[str]

    def space_json(self) -> dict[str, Any]:
        return {label: domain.model_dump() for label, domain in self.space.items()}


def validate_graph(graph: Graph) -> None:
    """Structural rules beyond the wire model's: raise GraphError naming the field."""
    ids: dict[str, int] = {}
    failures = 0
    decision_labels: dict[str, int] = {}
    for i, node in enumerate(graph.nodes):
        if node.id in ids:
            raise GraphError(f"nodes[{i}].id: duplicate node id {node.id!r}")
        ids[node.id] = i
        if node.role == "failure":
            failures += 1
        if node.role == "decision":
            if node.domain is None:
                raise GraphError(f"nodes[{i}].domain: decision node {node.id!r} needs a domain")
            if node.label in decision_labels:
                raise GraphError(
                    f"nodes[{i}].label: decision label {node.label!r} is used twice "
                    f"(also nodes[{decision_labels[node.label]}])"
                )
            decision_labels[node.label] = i
        elif node.domain is not None:
            raise GraphError(f"nodes[{i}].domain: only decision nodes carry a domain")
    if failures != 1:
        raise GraphError(f"nodes: a causal graph has exactly one failure node, found {failures}")
    if not decision_labels:
        raise GraphError("nodes: a causal graph needs at least one decision node")
    seen: set[tuple[str, str]] = set()
    for j, edge in enumerate(graph.edges):
        for end in ("source", "target"):
            if getattr(edge, end) not in ids:
                raise GraphError(f"edges[{j}].{end}: no node with id {getattr(edge, end)!r}")
        if edge.source == edge.target:
            raise GraphError(f"edges[{j}]: an edge from a node to itself")
        if (edge.source, edge.target) in seen:
            raise GraphError(f"edges[{j}]: a second edge {edge.source!r} -> {edge.target!r}")
        seen.add((edge.source, edge.target))


def _digraph(graph: Graph) -> nx.DiGraph:
    g = nx.DiGraph()
    for node in graph.nodes:
        domain = node.domain.model_dump() if node.domain is not None else None
        g.add_node(
            node.id, wl=f"{node.role}:{node.label}", role=node.role, label=node.label, domain=domain
        )
    for edge in graph.edges:
        g.add_edge(edge.source, edge.target, label=edge.label)
    return g


def _ascii(text: str) -> str:
    """networkx hashes labels as ASCII: escape the rest (and backslashes, to stay one-to-one)."""
    return text.replace("\\", "\\\\").encode("ascii", "backslashreplace").decode("ascii")


def _wl_graph(graph: Graph) -> nx.DiGraph:
    """The graph to hash: a node per vertex (`role:label`) and per edge (`edge:label`)."""
    g = nx.DiGraph()
    for node in graph.nodes:
        g.add_node(("v", node.id), wl=_ascii(f"{node.role}:{node.label}"))
    for i, edge in enumerate(graph.edges):
        g.add_node(("e", i), wl=_ascii(f"edge:{edge.label}"))
        g.add_edge(("v", edge.source), ("e", i))
        g.add_edge(("e", i), ("v", edge.target))
    return g


def wl_hashes(wl: nx.DiGraph) -> tuple[str, dict[Any, list[str]]]:
    """networkx's `weisfeiler_lehman_graph_hash` of `wl` and its
    `weisfeiler_lehman_subgraph_hashes`, from one pass: the graph hash is the hash of each
    iteration's node labels counted (in label order, iteration after iteration), and those
    labels are the subgraph hashes."""
    hashes = nx.weisfeiler_lehman_subgraph_hashes(wl, node_attr="wl", iterations=WL_ITERATIONS)
    counts: list[tuple[str, int]] = []
    for i in range(WL_ITERATIONS):
        counts.extend(sorted(Counter(labels[i] for labels in hashes.values()).items()))
    return blake2b(str(tuple(counts)).encode("ascii"), digest_size=16).hexdigest(), hashes


def _canonical(graph: Graph, hashes: Mapping[Any, list[str]]) -> dict[str, Any]:
    """Node ids renamed n0, n1, ... in an order fixed by role, label and WL neighbourhood
    (`hashes`: the subgraph hashes of `_wl_graph(graph)`)."""
    subtree = {node_id: hashes[("v", node_id)] for kind, node_id in hashes if kind == "v"}
    order = sorted(
        graph.nodes, key=lambda n: (ROLE_ORDER[n.role], n.label, tuple(subtree[n.id]), n.id)
    )
    rename = {node.id: f"n{i}" for i, node in enumerate(order)}
    nodes = []
    for node in order:
        item = node.model_dump(exclude_none=True)
        item["id"] = rename[node.id]
        nodes.append(item)
    edges = sorted(
        (
            {"source": rename[e.source], "target": rename[e.target], "label": e.label}
            for e in graph.edges
        ),
        key=lambda e: (int(e["source"][1:]), int(e["target"][1:]), e["label"]),
    )
    return {"nodes": nodes, "edges": edges}


@lru_cache(maxsize=4096)
def _resolve_json(graph_json: str) -> ResolvedGraph:
    graph = Graph.model_validate_json(graph_json)
    validate_graph(graph)
    type_id, hashes = wl_hashes(_wl_graph(graph))
    space = {n.label: n.domain for n in graph.nodes if n.role == "decision" and n.domain}
    return ResolvedGraph(
        type_id=type_id,
        canonical=_canonical(graph, hashes),
        space=dict(sorted(space.items())),
        failure=next(n.label for n in graph.nodes if n.role == "failure"),
        decisions=sorted(space),
        context=sorted(n.label for n in graph.nodes if n.role == "context"),
    )


def resolve_graph(graph: Graph) -> ResolvedGraph:
    """Validate `graph` and compute its type (GraphError if invalid)."""
    return _resolve_json(graph.model_dump_json())


def check_same_type(new: ResolvedGraph, stored_graph: dict[str, Any]) -> None:
    """Raise TypeConflict unless `new` is the stored type: isomorphic, same decision domains."""
    if new.canonical == stored_graph:
        return
    _check_isomorphic(new.type_id, _freeze(new.canonical), _freeze(stored_graph))


def _freeze(graph: dict[str, Any]) -> str:
    return Graph.model_validate(graph).model_dump_json()


@lru_cache(maxsize=1024)
def _check_isomorphic(type_id: str, new_json: str, stored_json: str) -> None:
    new = Graph.model_validate_json(new_json)
    stored = Graph.model_validate_json(stored_json)
    g_new, g_stored = _digraph(new), _digraph(stored)
    matcher = DiGraphMatcher(
        g_new,
        g_stored,
        node_match=lambda a, b: a["wl"] == b["wl"],
        edge_match=lambda a, b: a["label"] == b["label"],
    )
    if not matcher.is_isomorphic():
        raise TypeConflict(
            f"type {type_id}: the graph has the same Weisfeiler-Lehman hash as the stored "
            "type but is not isomorphic to it (a hash collision); relabel a node to tell them apart"
        )
    stored_space = {n.label: n.domain for n in stored.nodes if n.role == "decision"}
    for node in new.nodes:
        stored_domain = stored_space.get(node.label)
        if node.role == "decision" and not _same_values(node.domain, stored_domain):
            raise TypeConflict(
                f"type {type_id}: decision {node.label!r} has domain "
                f"{node.domain.model_dump() if node.domain else None}, but the stored type has "
                f"{stored_domain.model_dump() if stored_domain else None}"
            )


def _same_values(new: Domain | None, stored: Domain | None) -> bool:
    """Equal domains, but for a continuous `frame`, `heading`, `scale` and `periodic` and a
    categorical `embedding`: they say how the surrogate encodes the values, not which values
    there are, and a type stored with other ones (or before they existed) keeps its own encoding
    rather than refusing the planners that now send them."""
    if isinstance(new, ContinuousDomain) and isinstance(stored, ContinuousDomain):
        unframed = {"frame": None, "heading": None, "scale": None, "periodic": None}
        return new.model_copy(update=unframed) == stored.model_copy(update=unframed)
    if isinstance(new, CategoricalDomain) and isinstance(stored, CategoricalDomain):
        return new.choices == stored.choices
    return new == stored


def check_xs(xs: Sequence[Mapping[str, Value]], space: Mapping[str, Any], where: str) -> None:
    """`check_x` for each point of a list, as a post checks its points; errors name the point
    (`x[3].#pose[0]: ...`)."""
    for i, x in enumerate(xs):
        try:
            check_x(x, space)
        except GraphError as exc:
            raise GraphError(f"{where}[{i}]{str(exc).removeprefix('x')}") from exc


def check_x(x: Mapping[str, Value], space: Mapping[str, Any]) -> None:
    """Raise GraphError (message names the label) unless `x` is one value per decision. Any
    domain with the wire contract's fields will do (the surrogate library's as well)."""
    missing = [label for label in space if label not in x]
    if missing:
        raise GraphError(f"x: missing value for decision {missing[0]!r}")
    extra = [label for label in x if label not in space]
    if extra:
        raise GraphError(f"x.{extra[0]}: not a decision of this graph ({sorted(space)})")
    for label, domain in space.items():
        value = x[label]
        if domain.kind == "categorical":
            if not isinstance(value, str):
                raise GraphError(f"x.{label}: expected one of {domain.choices}, got {value!r}")
            if value not in domain.choices:
                raise GraphError(f"x.{label}: {value!r} is not one of {domain.choices}")
            continue
        if isinstance(value, str):
            raise GraphError(f"x.{label}: expected a list of {len(domain.low)} numbers")
        if len(value) != len(domain.low):
            raise GraphError(f"x.{label}: expected {len(domain.low)} numbers, got {len(value)}")
        for i, (v, lo, hi) in enumerate(zip(value, domain.low, domain.high, strict=True)):
            if not math.isfinite(v):
                raise GraphError(f"x.{label}[{i}]: {v} is not a finite number")
            if not lo <= v <= hi:
                raise GraphError(f"x.{label}[{i}]: {v} is outside [{lo}, {hi}]")

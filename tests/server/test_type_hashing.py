"""Type IDs: invariant to node ids, sensitive to labels, roles, edges; collisions caught."""

from __future__ import annotations

from typing import Any

import networkx as nx
import pytest
from service_support import collision_pair, make_graph

from contract.models import Graph
from server.graphs import (
    WL_ITERATIONS,
    GraphError,
    TypeConflict,
    _wl_graph,
    check_same_type,
    check_x,
    resolve_graph,
    wl_hashes,
)


def resolve(graph: dict[str, Any]) -> Any:
    return resolve_graph(Graph.model_validate(graph))


def test_renamed_reordered_graph_has_the_same_type_and_canonical_form() -> None:
    a = resolve(make_graph(context=("box1", "box2")))
    other = make_graph(context=("box1", "box2"), prefix="zz-")
    other["nodes"] = other["nodes"][::-1]
    b = resolve(other)
    assert a.type_id == b.type_id and len(a.type_id) == 32
    assert a.canonical == b.canonical
    check_same_type(b, a.canonical)


@pytest.mark.parametrize(
    ("graph", "type_id"),
    [
        (make_graph(), "eae1065e9193ba4582bebf796559ec38"),
        (make_graph(context=("box1", "box2")), "fbf820f0bb3f621c3a4704a0f766d47e"),
        (collision_pair()[0], "ce14910c34bfc30ebd9dbee72176f325"),
        (collision_pair()[1], "ce14910c34bfc30ebd9dbee72176f325"),
    ],
)
def test_type_ids_are_networkx_weisfeiler_lehman_hashes(
    graph: dict[str, Any], type_id: str
) -> None:
    """The hash worked out from the subgraph hashes is networkx's graph hash, and the type IDs
    that knowledge bases hold do not change (those of an earlier commit, pinned)."""
    wl = _wl_graph(Graph.model_validate(graph))
    expected = nx.weisfeiler_lehman_graph_hash(wl, node_attr="wl", iterations=WL_ITERATIONS)
    assert wl_hashes(wl)[0] == expected == type_id == resolve(graph).type_id


@pytest.mark.parametrize(
    "variant",
    [
        make_graph(failure="Plan-motion"),
        make_graph(context=("box2",)),
        make_graph(context=()),
        make_graph(context=("box1", "box1")),
    ],
)
def test_labels_and_structure_change_the_type(variant: dict[str, Any]) -> None:
    assert resolve(variant).type_id != resolve(make_graph()).type_id


def test_edge_labels_and_direction_change_the_type() -> None:
    relabelled = make_graph()
    relabelled["edges"][0]["label"] = "other"
    reversed_edge = make_graph()
    edge = reversed_edge["edges"][2]
    edge["source"], edge["target"] = edge["target"], edge["source"]
    base = resolve(make_graph()).type_id
    assert resolve(relabelled).type_id != base
    assert resolve(reversed_edge).type_id != base


def test_domain_is_not_hashed_but_checked() -> None:
    a = resolve(make_graph())
    b = resolve(make_graph(pose_domain={"kind": "continuous", "low": [0], "high": [1]}))
    assert a.type_id == b.type_id
    with pytest.raises(TypeConflict, match="'#pose'"):
        check_same_type(b, a.canonical)


def test_a_frame_added_to_a_stored_type_is_the_same_type() -> None:
    """A type stored before frames existed still answers planners that now send one."""
    stored = resolve(make_graph(pose_domain={"kind": "continuous", "low": [0], "high": [1]}))
    framed = {"kind": "continuous", "low": [0], "high": [1], "frame": "region5"}
    resolved = resolve(make_graph(pose_domain=framed))
    assert resolved.type_id == stored.type_id
    check_same_type(resolved, stored.canonical)
    moved = {"kind": "continuous", "low": [0], "high": [2], "frame": "region5"}
    with pytest.raises(TypeConflict, match="'#pose'"):
        check_same_type(resolve(make_graph(pose_domain=moved)), stored.canonical)


def test_a_heading_added_to_a_stored_framed_type_is_the_same_type() -> None:
    """A type stored with frames only (before headings existed) keeps answering."""
    framed = {"kind": "continuous", "low": [0, 0, 0], "high": [1, 1, 1], "frame": "region5"}
    stored = resolve(make_graph(pose_domain=framed))
    resolved = resolve(make_graph(pose_domain={**framed, "heading": 2}))
    assert resolved.type_id == stored.type_id
    check_same_type(resolved, stored.canonical)


def test_a_scale_or_another_embedding_is_the_same_type() -> None:
    """Metric frames and grasp symmetries say how values are encoded, not which there are: a
    type stored without them (or by a task with other extents) keeps its own encoding."""
    framed = {"kind": "continuous", "low": [0, 0, 0], "high": [1, 1, 1], "frame": "region5"}
    stored = resolve(make_graph(pose_domain={**framed, "heading": 2}))
    scaled = {**framed, "heading": 2, "scale": [0.3, 0.1]}
    check_same_type(resolve(make_graph(pose_domain=scaled)), stored.canonical)
    grasps = next(n["domain"] for n in make_graph()["nodes"] if n["label"] == "#dir")
    symmetric = {**grasps, "embedding": {c: [1.0, 0.0] for c in grasps["choices"]}}
    graph = make_graph(pose_domain={**framed, "heading": 2})
    for node in graph["nodes"]:
        if node["label"] == "#dir":
            node["domain"] = symmetric
    check_same_type(resolve(graph), stored.canonical)
    fewer = {**grasps, "choices": grasps["choices"][:-1], "embedding": None}
    for node in graph["nodes"]:
        if node["label"] == "#dir":
            node["domain"] = fewer
    with pytest.raises(TypeConflict, match="'#dir'"):
        check_same_type(resolve(graph), stored.canonical)


def test_collision_pair_shares_a_hash_but_conflicts() -> None:
    six, threes = (resolve(g) for g in collision_pair())
    assert six.type_id == threes.type_id
    with pytest.raises(TypeConflict, match="not isomorphic"):
        check_same_type(threes, six.canonical)


def test_x_is_checked_against_the_space() -> None:
    space = resolve(make_graph()).space
    check_x({"#dir": "top", "#pose": [0.0, 1.0, 3.0]}, space)
    with pytest.raises(GraphError, match=r"x.#pose\[2\]: inf is not a finite number"):
        check_x({"#dir": "top", "#pose": [0.0, 1.0, float("inf")]}, space)


def test_graph_rules() -> None:
    no_decision = {"nodes": [{"id": "f", "role": "failure", "label": "x"}], "edges": []}
    with pytest.raises(GraphError, match="at least one decision"):
        resolve(no_decision)

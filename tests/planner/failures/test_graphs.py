"""Causal graphs of failed transitions: vertexes, task-independent labels, stable identity."""

from __future__ import annotations

import numpy as np
import pytest

from contract.models import CategoricalDomain, ContinuousDomain
from planner.failures import Encodings, failure_graph
from planner.search.analytic import GRASP_DOMAIN, analytic_world, pick_place_skeleton
from planner.skeleton import DecisionVar, Layer, OperatorCall, Skeleton
from planner.tasks import grasp_domain, pose_domain
from planner.world import CheckResult, Culprit, WorldGeometry
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder

POSE = ContinuousDomain(low=[0.0] * 3, high=[1.0] * 3)


def roles(graph) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for n in graph.nodes:
        out.setdefault(n.role, set()).add(n.label)
    return out


def blocked_grasp(task: str):
    world = analytic_world(task)
    outcome = world.transition(0, {"#dir1": "right"}, None)
    assert outcome.failed is not None
    return failure_graph(world.skeleton, 0, outcome.failed)


def test_a_blocked_grasp_has_failure_decision_and_obstacle_vertexes():
    fg = blocked_grasp("desk")
    assert roles(fg.graph) == {
        "failure": {"Inv-kin"},
        "decision": {"#dir"},
        "context": {"body", "pose0", "obstacle2"},
    }
    edges = {(e.source, e.target, e.label) for e in fg.graph.edges}
    assert ("c:obstacle2", "failure", "collides") in edges
    assert ("d:#dir", "failure", "arg2") in edges
    decision = next(n for n in fg.graph.nodes if n.role == "decision")
    assert decision.domain == GRASP_DOMAIN
    assert fg.bind == {"#dir": "#dir1"} and fg.check == (0, 0)
    assert fg.x({"#dir1": "right"}) == {"#dir": "right"}


def test_the_graph_is_the_same_on_every_run():
    assert blocked_grasp("desk").graph == blocked_grasp("desk").graph


def test_a_shelf_failure_gives_the_same_graph_in_deskP_and_desk():
    graphs = []
    for task in ("deskP", "desk"):
        world = analytic_world(task)
        outcome = world.transition(1, {"#dir1": "front", "#pose12": [0.1, 0.9, 0.5]}, None)
        graphs.append(failure_graph(world.skeleton, 1, outcome.failed))
    assert graphs[0].graph == graphs[1].graph
    assert roles(graphs[0].graph)["decision"] == {"#dir", "#pose"}
    assert "region2" in roles(graphs[0].graph)["context"]


def test_a_motion_failure_backtracks_through_the_configurations():
    skeleton = pick_place_skeleton("pose0", "region2")
    call = skeleton.transitions[1].calls[1]  # Plan-motion(#config1, #config2)
    fg = failure_graph(skeleton, 1, CheckResult(call, False, culprits=(Culprit("shelf", 0.01),)))
    assert roles(fg.graph)["connection"] == {"Inv-kin"}
    assert len([n for n in fg.graph.nodes if n.role == "connection"]) == 2
    assert fg.bind == {"#dir": "#dir1", "#pose": "#pose12"}


def regrasp_skeleton(
    grasps: CategoricalDomain = GRASP_DOMAIN, pose: ContinuousDomain = POSE
) -> Skeleton:
    def grasp(out: str) -> Layer:
        call = OperatorCall("Sample-grasp", ("body",), (out,))
        return Layer("decision", (call,), DecisionVar(out, "#dir", grasps, call))

    def place(out: str, region: str) -> Layer:
        call = OperatorCall("Sample-pose", ("body", region), (out,))
        return Layer("decision", (call,), DecisionVar(out, "#pose", pose, call))

    def move(pose_arg: str, dir_arg: str, c0: str, c1: str, op: str) -> Layer:
        return Layer(
            "transition",
            (
                OperatorCall("Inv-kin", ("body", pose_arg, dir_arg), (c1,)),
                OperatorCall("Plan-motion", (c0, c1), (f"#traj-{c1}",)),
                OperatorCall(op, ("body", f"#traj-{c1}")),
            ),
        )

    return Skeleton(
        (
            grasp("#dir1"),
            move("pose0", "#dir1", "config0", "#config1", "Move-Pick"),
            place("#pose13", "region3"),
            move("#pose13", "#dir1", "#config1", "#config2", "Move-Place"),
            grasp("#dir2"),
            move("#pose13", "#dir2", "#config2", "#config3", "Move-Pick"),
            place("#pose12", "region2"),
            move("#pose12", "#dir2", "#config3", "#config4", "Move-Place"),
        )
    )


def test_regrasp_keeps_its_two_grasps_apart_and_binds_them_to_this_task():
    skeleton = regrasp_skeleton()
    # Plan-motion(#config2, #config3) at the regrasp: #config2 from the first grasp, #config3
    # from the second, both at #pose13.
    call = skeleton.transitions[2].calls[1]
    fg = failure_graph(skeleton, 2, CheckResult(call, False))
    labels = sorted(n.label for n in fg.graph.nodes if n.role == "decision")
    assert labels == ["#dir", "#dir-1", "#pose"]
    assert fg.bind == {"#dir": "#dir2", "#dir-1": "#dir1", "#pose": "#pose13"}


def test_the_last_grasp_of_regrasp_looks_like_the_first_grasp_of_desk():
    skeleton = regrasp_skeleton()
    final_ik = skeleton.transitions[3].calls[0]  # Inv-kin(body, #pose12, #dir2)
    regrasp = failure_graph(
        skeleton, 3, CheckResult(final_ik, False, culprits=(Culprit("shelf", 0.01),))
    )
    desk_skeleton = pick_place_skeleton("pose0", "region2")
    desk = failure_graph(
        desk_skeleton,
        1,
        CheckResult(
            desk_skeleton.transitions[1].calls[0], False, culprits=(Culprit("shelf", 0.01),)
        ),
    )
    assert regrasp.graph == desk.graph
    assert regrasp.bind == {"#pose": "#pose12", "#dir": "#dir2"}


def test_a_culprit_placed_by_an_earlier_decision_links_to_that_decision():
    skeleton = regrasp_skeleton()
    # Pretend the body placed at #pose13 is what the second pick collides with.
    call = skeleton.transitions[2].calls[0]
    fg = failure_graph(skeleton, 2, CheckResult(call, False, culprits=(Culprit("body", 0.02),)))
    edges = {(e.source, e.target, e.label) for e in fg.graph.edges}
    assert ("d:#pose", "c:body", "at") in edges
    assert fg.bind["#pose"] == "#pose13"


def test_a_culprit_that_is_also_an_argument_gives_one_edge_with_both_relations():
    skeleton = pick_place_skeleton("pose0", "region2")
    call = skeleton.transitions[0].calls[0]  # Inv-kin(body, pose0, #dir1)
    fg = failure_graph(skeleton, 0, CheckResult(call, False, culprits=(Culprit("body", 0.01),)))
    pairs = [(e.source, e.target) for e in fg.graph.edges]
    assert len(pairs) == len(set(pairs))
    assert ("c:body", "failure", "arg0+collides") in {
        (e.source, e.target, e.label) for e in fg.graph.edges
    }


def test_placing_with_a_grasp_and_grasping_at_a_place_are_different_graphs():
    """Inv-kin(body, #pose13, #dir1) places the held body; Inv-kin(body, #pose13, #dir2) grasps
    it where it was put: the same call shape, different constraints."""
    skeleton = regrasp_skeleton()
    place = failure_graph(skeleton, 1, CheckResult(skeleton.transitions[1].calls[0], False))
    pick = failure_graph(skeleton, 2, CheckResult(skeleton.transitions[2].calls[0], False))
    assert roles(place.graph) == roles(pick.graph)
    assert ("d:#dir", "d:#pose", "then") in {
        (e.source, e.target, e.label) for e in place.graph.edges
    }
    assert ("d:#pose", "d:#dir", "then") in {
        (e.source, e.target, e.label) for e in pick.graph.edges
    }
    assert place.graph != pick.graph


def grasp_domain_of(fg) -> object:
    return next(n.domain for n in fg.graph.nodes if n.label == "#dir")


def with_footprint(size: tuple[float, float], **switches: bool) -> Encodings:
    return Encodings(WorldGeometry(body_sizes=(("body", (*size, 0.1)),)), **switches)


def encoded_grasps(fg) -> dict[str, tuple[float, ...]]:
    """The GP input row of each grasp choice, as the surrogate encodes the graph's grasp."""
    domain = grasp_domain_of(fg)
    encoder = SpaceEncoder(space_from_json({"#dir": domain.model_dump()}))
    return {
        choice: tuple(np.round(encoder.encode({"#dir": np.array([i])})[0], 9))
        for i, choice in enumerate(domain.choices)
    }


@pytest.mark.parametrize("grasps", [GRASP_DOMAIN, grasp_domain()])
def test_a_rectangular_box_being_placed_sees_opposite_faces_alike(grasps):
    """A 0.04 x 0.08 box: front and back place alike, right and left alike, front not right."""
    skeleton = regrasp_skeleton(grasps)
    shelf_ik = CheckResult(skeleton.transitions[3].calls[0], False)  # Inv-kin(body, #pose12, #dir2)
    box = with_footprint((0.04, 0.08))
    rows = encoded_grasps(failure_graph(skeleton, 3, shelf_ik, encodings=box))
    assert rows["front"] == rows["back"] and rows["right"] == rows["left"]
    assert rows["front"] != rows["right"]
    assert rows["top"] not in {rows["front"], rows["right"]}


@pytest.mark.parametrize("size", [(0.06, 0.06), (0.06, 0.0605)])
def test_a_square_body_being_placed_sees_its_side_grasps_as_one(size):
    skeleton = regrasp_skeleton()
    shelf_ik = CheckResult(skeleton.transitions[3].calls[0], False)
    held = grasp_domain_of(failure_graph(skeleton, 3, shelf_ik, encodings=with_footprint(size)))
    assert held.choices == GRASP_DOMAIN.choices
    sides = {tuple(held.embedding[c]) for c in ("front", "right", "back", "left")}
    assert sides == {(1.0, 0.0)} and held.embedding["top"] == [0.0, 1.0]
    rows = encoded_grasps(failure_graph(skeleton, 3, shelf_ik, encodings=with_footprint(size)))
    assert len({rows[c] for c in ("front", "right", "back", "left")}) == 1
    assert rows["top"] != rows["front"]


def test_grasps_keep_their_declared_encoding_where_no_placement_or_switched_off():
    skeleton = regrasp_skeleton()
    box = with_footprint((0.04, 0.08))
    shelf_ik = CheckResult(skeleton.transitions[3].calls[0], False)
    pick_ik = CheckResult(skeleton.transitions[2].calls[0], False)  # the regrasp picks at #pose13
    assert grasp_domain_of(failure_graph(skeleton, 2, pick_ik, encodings=box)) == GRASP_DOMAIN
    assert grasp_domain_of(failure_graph(skeleton, 3, shelf_ik)) == GRASP_DOMAIN  # no geometry
    off = with_footprint((0.04, 0.08), grasp_symmetry=False)
    assert grasp_domain_of(failure_graph(skeleton, 3, shelf_ik, encodings=off)) == GRASP_DOMAIN
    square_off = with_footprint((0.06, 0.06), square_grasps=False, grasp_symmetry=False)
    assert grasp_domain_of(failure_graph(skeleton, 3, shelf_ik, encodings=square_off)) == (
        GRASP_DOMAIN
    )
    square_only = with_footprint((0.06, 0.06), grasp_symmetry=False)
    assert (
        len(
            set(
                encoded_grasps(failure_graph(skeleton, 3, shelf_ik, encodings=square_only)).values()
            )
        )
        == 2
    )  # sides and top


def test_without_movable_names_one_box_beside_another_is_one_type_whichever_boxes():
    """Pack's second box placed against its first and its third against its second: with
    movable bodies labelled `movable` one type (by the service's hash), each bound to its own
    placements; by name (the default, the paper's) two types. Obstacles keep their names."""
    from planner.tasks import build_skeleton, load_task
    from server.graphs import resolve_graph

    task = load_task("pack")
    skeleton = build_skeleton(task)
    geometry = WorldGeometry(
        body_sizes=tuple((b.name, tuple(b.size)) for b in task.bodies.values())
    )

    def beside(layer: int, body: str, earlier: str, names: bool):
        call = next(c for c in skeleton.transitions[layer].calls if c.args[1].startswith("#pose"))
        check = CheckResult(call, False, culprits=(Culprit(earlier, 0.01), Culprit("tray", 0.0)))
        encodings = Encodings(geometry, movable_names=names)
        return failure_graph(skeleton, layer, check, encodings=encodings)

    second, third = beside(1, "body2", "body1", False), beside(2, "body3", "body2", False)
    assert resolve_graph(second.graph).type_id == resolve_graph(third.graph).type_id
    assert (second.bind["#pose"], second.bind["#pose-1"]) == ("#pose2", "#pose1")
    assert (third.bind["#pose"], third.bind["#pose-1"]) == ("#pose3", "#pose2")
    assert roles(second.graph)["context"] == {"movable", "region5", "top"}
    named = beside(1, "body2", "body1", True), beside(2, "body3", "body2", True)
    assert resolve_graph(named[0].graph).type_id != resolve_graph(named[1].graph).type_id
    tray = CheckResult(skeleton.transitions[1].calls[3], False, culprits=(Culprit("tray", 0.01),))
    tray_graph = failure_graph(
        skeleton, 1, tray, encodings=Encodings(geometry, movable_names=False)
    )
    assert roles(tray_graph.graph)["context"] == {"movable", "region5", "top", "tray"}


def test_with_relative_pairs_a_placement_is_marked_relative_only():
    """The switch marks every framed planar pose of a graph; the encoder then drops its own
    columns only where the type holds a pair of them. Off, the domain is the declared one, so
    the paper's types keep their ids."""
    skeleton = regrasp_skeleton(pose=pose_domain("region2"))
    shelf_ik = CheckResult(skeleton.transitions[3].calls[0], False)

    def pose_of(encodings: Encodings):
        graph = failure_graph(skeleton, 3, shelf_ik, encodings=encodings).graph
        return next(n.domain for n in graph.nodes if n.label == "#pose")

    marked = pose_of(Encodings(relative_pairs=True))
    assert marked.relative_only and marked.scale is None
    assert pose_of(Encodings()).relative_only is None


def test_with_periodic_headings_a_placement_is_marked_periodic():
    """The switch marks every framed planar pose; off, the declared domain is kept, so the
    paper's types keep their ids."""
    skeleton = regrasp_skeleton(pose=pose_domain("region2"))
    shelf_ik = CheckResult(skeleton.transitions[3].calls[0], False)

    def pose_of(encodings: Encodings):
        graph = failure_graph(skeleton, 3, shelf_ik, encodings=encodings).graph
        return next(n.domain for n in graph.nodes if n.label == "#pose")

    assert pose_of(Encodings(periodic_headings=True)).periodic
    assert pose_of(Encodings()).periodic is None

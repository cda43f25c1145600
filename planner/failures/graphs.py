"""Backtracking a failed transition into its causal graph (DESIGN.md section 3, paper IV-A).

From the failed operator call, semantic backtracking follows its `#` arguments through the
skeleton: a variable produced by a decision layer becomes a *decision* vertex (the leaf of the
chain, with its producer's constant arguments as context), one produced by a transition call
becomes a *connection* vertex labelled by that operator, and the chain continues through its
arguments. Constants (bodies, regions, `pose0`, `config0`) are *context* vertexes. Geometric
backtracking adds the culprit the simulator names: a context vertex for that body, linked to the
decision vertex that placed it when an earlier decision of this skeleton did; so is a movable
body a placement stacks on (`Sample-pose(body, other_body)`), which is named like any region.
An arm other than the Panda is a context vertex of every failure (`arm:<its URDF>`), so that
what is learnt with one arm does not steer another.

Labels are task-independent: operator names, workspace constant and body names, and decision
kinds. Decision labels stay unique by recency: the latest `#dir` in the graph is `#dir`, the one
before `#dir-1`, and so on, so the two grasps of the regrasp task stay apart while a failure at
the first grasp of any task gets the same labels. `bind` maps those labels back to this task's
variables. Decisions are chained in the order they were taken (`then` edges): placing a held body
(`Inv-kin(body, #pose, #dir)` with the grasp chosen first) and grasping a body where it was put
(the same call with the place chosen first) are different constraints, not one type.

Encodings from geometry (`Encodings`, each switchable by configuration), from what the world
tells (`WorldGeometry`, in metres), never from a list of the shipped scenes' bodies:

- A grasp that holds a body being placed is encoded as the placing hand sees it
  (`held_grasp_domain`). A placement's yaw is the hand's heading, so two grasps on opposite
  faces of a box (front and back, right and left) put the same hand pose over the same
  footprint turned half a turn, which a box cannot tell apart: they are one. Where the
  footprint is square (within `SQUARE_TOLERANCE`) all four side grasps are one (all 60 shelf
  placements tried with `front` and `right` agreed). The top grasp stays apart. Switches:
  `square_grasps` (square footprints), `grasp_symmetry` (opposite faces of any box).
- With `relative_pairs`, a type holding two placements of one region sees only their relative
  pose (`surrogate.encoding`).
- A placement's heading is an angle: with `periodic_headings` its model sees it on a circle,
  where the two ends of the seed's range are one heading (`surrogate.encoding`).
- A movable body's vertex can be labelled `movable` instead of its name (`movable_names`
  off): a name says nothing about a box's geometry, and two boxes of a task are as alike as
  the same two names in another, so that placing one box next to another is one constraint
  whichever boxes they are (the second box beside the first and the third beside the second
  of a pack).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from contract.models import CategoricalDomain, ContinuousDomain, Domain, Edge, Graph, Node
from planner.skeleton import DecisionVar, OperatorCall, Skeleton
from planner.world import CheckResult, WorldGeometry

PLACE_KINDS = ("#pose",)
GRASP_KINDS = ("#dir",)
SQUARE_TOLERANCE = 1e-3
"""Metres by which a footprint's sides may differ and it still counts as square."""
MOVABLE_LABEL = "movable"


@dataclass(frozen=True)
class Encodings:
    """The encodings from geometry a graph's decisions get; with both off (or no geometry), the
    domains as the skeleton declares them (the paper's encoding)."""

    geometry: WorldGeometry = field(default_factory=WorldGeometry)
    square_grasps: bool = True
    grasp_symmetry: bool = True
    relative_pairs: bool = False
    periodic_headings: bool = False
    movable_names: bool = True


@dataclass(frozen=True)
class FailureGraph:
    """A causal graph plus how its decision labels map to this task's decision variables."""

    graph: Graph
    bind: dict[str, str]
    check: tuple[int, int]
    culprit: str | None = None

    def x(self, bindings: dict) -> dict:
        """The point for this graph's type: the values of its decision vertexes."""
        return {label: bindings[var] for label, var in self.bind.items()}


class _Builder:
    def __init__(self, skeleton: Skeleton, transition_index: int) -> None:
        self.skeleton = skeleton
        self.nodes: dict[str, Node] = {}
        self.edges: list[Edge] = []
        self.decisions: dict[str, DecisionVar] = {}
        self.producers: dict[str, OperatorCall] = {}
        self.decision_of: dict[str, DecisionVar] = {}
        transitions_seen = 0
        for layer in skeleton.layers:
            if layer.kind == "transition":
                if transitions_seen > transition_index:
                    break
                transitions_seen += 1
            if layer.decision is not None:
                self.decision_of[layer.decision.var] = layer.decision
            for call in layer.calls:
                for out in call.outputs:
                    self.producers[out] = call

    def context(self, name: str) -> str:
        node_id = f"c:{name}"
        self.nodes.setdefault(node_id, Node(id=node_id, role="context", label=name))
        return node_id

    def edge(self, source: str, target: str, label: str) -> None:
        """One edge per ordered pair (the contract has no parallel edges): a second relation
        between the same vertexes joins the label, e.g. `arg0+collides` for a held body that is
        also the culprit."""
        for i, existing in enumerate(self.edges):
            if (existing.source, existing.target) == (source, target):
                labels = sorted({*existing.label.split("+"), label})
                self.edges[i] = Edge(source=source, target=target, label="+".join(labels))
                return
        self.edges.append(Edge(source=source, target=target, label=label))

    def consume(self, call: OperatorCall, target: str) -> None:
        """Link every argument of `call` into `target`, backtracking `#` variables."""
        for position, arg in enumerate(call.args):
            self.edge(self.source_of(arg), target, f"arg{position}")

    def source_of(self, arg: str) -> str:
        if not arg.startswith("#"):
            return self.context(arg)
        if arg in self.decision_of:
            return self.decision(self.decision_of[arg])
        producer = self.producers.get(arg)
        if producer is None:
            raise ValueError(f"no call of the skeleton produces {arg}")
        node_id = f"x:{arg}"
        if node_id not in self.nodes:
            self.nodes[node_id] = Node(id=node_id, role="connection", label=producer.name)
            self.consume(producer, node_id)
        return node_id

    def decision(self, var: DecisionVar) -> str:
        node_id = f"d:{var.var}"
        if node_id not in self.nodes:
            self.nodes[node_id] = Node(id=node_id, role="decision", label=var.kind)
            self.decisions[var.var] = var
            for position, arg in enumerate(var.producer.args):
                self.edge(self.context(arg), node_id, f"arg{position}")
            if var.kind in PLACE_KINDS and len(var.producer.args) > 1:
                # A place on a movable body's top (stacking) is where that body was put.
                support = var.producer.args[1]
                placing = self.placed_by(support, self.skeleton.decisions.index(var))
                if placing is not None:
                    self.edge(self.decision(placing), self.context(support), "at")
        return node_id

    def placed_by(self, body: str, before_transition: int) -> DecisionVar | None:
        """The latest placement decision of `body` whose transition completed earlier."""
        placing: DecisionVar | None = None
        for index, var in enumerate(self.skeleton.decisions):
            if index >= before_transition:
                break
            if var.kind in PLACE_KINDS and var.producer.args[:1] == (body,):
                placing = var
        return placing


def is_square(footprint: tuple[float, float]) -> bool:
    return abs(footprint[0] - footprint[1]) <= SQUARE_TOLERANCE


def held_grasp_domain(domain: CategoricalDomain, square: bool) -> CategoricalDomain:
    """The grasp as the hand placing a body sees it: each choice's approach vector (its
    embedding) without its signs, so that grasps on opposite faces are one; for a square
    footprint, reduced to its horizontal and vertical share, so that all side grasps are one."""
    if domain.embedding is None:
        return domain
    return domain.model_copy(
        update={
            "embedding": {
                choice: [math.hypot(*vector[:-1]), abs(vector[-1])]
                if square
                else [abs(v) for v in vector]
                for choice, vector in domain.embedding.items()
            }
        }
    )


def held_grasps(skeleton: Skeleton, call: OperatorCall) -> frozenset[str]:
    """The grasp variables of `call` that hold a body being placed by it: a grasp argument
    chosen before a placement argument of the same body."""
    order = {v.var: i for i, v in enumerate(skeleton.decisions)}
    kinds = {v.var: v.kind for v in skeleton.decisions}
    places = [order[a] for a in call.args if kinds.get(a) in PLACE_KINDS]
    return frozenset(
        a
        for a in call.args
        if kinds.get(a) in GRASP_KINDS and any(order[a] < place for place in places)
    )


def encoded_domains(
    skeleton: Skeleton, call: OperatorCall, chosen: dict[str, DecisionVar], encodings: Encodings
) -> dict[str, Domain]:
    """The domains the decisions of a graph failing at `call` are encoded with."""
    geometry = encodings.geometry
    footprint = geometry.footprint(call.args[0]) if call.args else None
    square = footprint is not None and is_square(footprint) and encodings.square_grasps
    symmetric = square or (footprint is not None and encodings.grasp_symmetry)
    held = held_grasps(skeleton, call) if symmetric else frozenset()
    out: dict[str, Domain] = {}
    for var, decision in chosen.items():
        domain = decision.domain
        if var in held and isinstance(domain, CategoricalDomain):
            domain = held_grasp_domain(domain, square)
        elif isinstance(domain, ContinuousDomain) and domain.heading is not None:
            update: dict[str, object] = {}
            if encodings.relative_pairs:
                update["relative_only"] = True
            if encodings.periodic_headings:
                update["periodic"] = True
            domain = domain.model_copy(update=update)
        out[var] = domain
    return out


def label_decisions(
    skeleton: Skeleton,
    nodes: dict[str, Node],
    chosen: dict[str, DecisionVar],
    domains: dict[str, Domain] | None = None,
) -> dict[str, str]:
    """Rename decision vertexes by recency within the graph: `#dir`, `#dir-1`, ...; each gets
    its domain from `domains` (`encoded_domains`), by default the declared one."""
    order = [v.var for v in skeleton.decisions]
    bind: dict[str, str] = {}
    by_kind: dict[str, list[str]] = {}
    for var in sorted(chosen, key=order.index, reverse=True):
        kind = chosen[var].kind
        rank = len(by_kind.setdefault(kind, []))
        by_kind[kind].append(var)
        label = kind if rank == 0 else f"{kind}-{rank}"
        node = nodes[f"d:{var}"]
        domain = chosen[var].domain if domains is None else domains[var]
        nodes[f"d:{var}"] = Node(id=node.id, role="decision", label=label, domain=domain)
        bind[label] = var
    return bind


def chain_decisions(builder: _Builder) -> None:
    """`then` edges from each decision of the graph to the next one taken."""
    order = [v.var for v in builder.skeleton.decisions]
    taken = sorted(builder.decisions, key=order.index)
    for earlier, later in itertools.pairwise(taken):
        builder.edge(f"d:{earlier}", f"d:{later}", "then")


def failure_graph(
    skeleton: Skeleton,
    transition_index: int,
    check: CheckResult,
    culprit: str | None = None,
    encodings: Encodings | None = None,
) -> FailureGraph:
    """The causal graph of `check` failing in transition layer `transition_index`.

    `culprit` overrides the check's first culprit (used to enumerate the graphs a task could
    produce); by default the body most in contact is taken, as the authors do. `encodings`:
    the encodings from the world's geometry (see the module docstring).
    """
    layer = skeleton.transitions[transition_index]
    call_index = layer.calls.index(check.call)
    builder = _Builder(skeleton, transition_index)
    builder.nodes["failure"] = Node(id="failure", role="failure", label=check.call.name)
    builder.consume(check.call, "failure")
    encodings = encodings if encodings is not None else Encodings()
    if encodings.geometry.arm:
        builder.edge(builder.context(f"arm:{encodings.geometry.arm}"), "failure", "arm")
    body = culprit if culprit is not None else (check.culprits[0].body if check.culprits else None)
    if body is not None:
        placing = builder.placed_by(body, transition_index)
        body_id = builder.context(body)
        builder.edge(body_id, "failure", "collides")
        if placing is not None:
            builder.edge(builder.decision(placing), body_id, "at")
    chain_decisions(builder)
    encodings = encodings if encodings is not None else Encodings()
    if not encodings.movable_names:
        _label_movable(builder.nodes, encodings.geometry)
    domains = encoded_domains(skeleton, check.call, builder.decisions, encodings)
    bind = label_decisions(skeleton, builder.nodes, builder.decisions, domains)
    graph = _task_independent_ids(builder.nodes, builder.edges)
    return FailureGraph(graph, bind, (transition_index, call_index), body)


def _label_movable(nodes: dict[str, Node], geometry: WorldGeometry) -> None:
    """Each movable body's context vertex labelled `movable` in place of its name (see
    `Encodings.movable_names`)."""
    for node_id, node in nodes.items():
        if node.role == "context" and geometry.size(node_id.removeprefix("c:")) is not None:
            nodes[node_id] = node.model_copy(update={"label": MOVABLE_LABEL})


def _task_independent_ids(nodes: dict[str, Node], edges: list[Edge]) -> Graph:
    """Rename vertexes after their labels (connections numbered in build order), so the same
    failure gives the very same graph in every task, not only the same type ID."""
    rename: dict[str, str] = {}
    connections = 0
    for node_id, node in nodes.items():
        if node.role == "decision":
            rename[node_id] = f"d:{node.label}"
        elif node.role == "connection":
            connections += 1
            rename[node_id] = f"x{connections}:{node.label}"
        else:
            rename[node_id] = node_id
    return Graph(
        nodes=[n.model_copy(update={"id": rename[i]}) for i, n in nodes.items()],
        edges=[
            Edge(source=rename[e.source], target=rename[e.target], label=e.label) for e in edges
        ],
    )

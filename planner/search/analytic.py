"""Small analytic worlds: the desk skeleton of Table I with closed-form checks, no simulator.

They implement `BindingWorld` so the tree search, the samplers and the knowledge-base loop can
be exercised (and compared) in milliseconds. `analytic_world("desk")` and `analytic_world("deskP")`
share one workspace: the same shelf region (`region2`) and the same shelf constraint, so a
failure type learned in deskP recurs in desk, as in the paper's Fig. 4.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import cast

from contract.models import CategoricalDomain, ContinuousDomain, Value
from planner.skeleton import DecisionVar, Layer, OperatorCall, Skeleton
from planner.world import CheckResult, Culprit, TransitionOutcome, WorldGeometry

DIRECTIONS = {
    "front": [-1.0, 0.0, 0.0],
    "right": [0.0, 1.0, 0.0],
    "top": [0.0, 0.0, -1.0],
    "back": [1.0, 0.0, 0.0],
    "left": [0.0, -1.0, 0.0],
}
GRASP_DOMAIN = CategoricalDomain(choices=list(DIRECTIONS), embedding=DIRECTIONS)
POSE_DOMAIN = ContinuousDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0])

# A check: the bindings so far -> None (passes) or the culprit bodies of its failure.
Check = Callable[[Mapping[str, Value]], tuple[str, ...] | None]


def pick_place_skeleton(start: str, goal_region: str) -> Skeleton:
    """Table I: grasp at `start`, place in `goal_region`."""
    grasp = OperatorCall("Sample-grasp", ("body",), ("#dir1",))
    place = OperatorCall("Sample-pose", ("body", goal_region), ("#pose12",))
    return Skeleton(
        (
            Layer("decision", (grasp,), DecisionVar("#dir1", "#dir", GRASP_DOMAIN, grasp)),
            Layer(
                "transition",
                (
                    OperatorCall("Inv-kin", ("body", start, "#dir1"), ("#config1",)),
                    OperatorCall("Plan-motion", ("config0", "#config1"), ("#traj01",)),
                    OperatorCall("Move-Pick", ("body", "#traj01")),
                ),
            ),
            Layer("decision", (place,), DecisionVar("#pose12", "#pose", POSE_DOMAIN, place)),
            Layer(
                "transition",
                (
                    OperatorCall("Inv-kin", ("body", "#pose12", "#dir1"), ("#config2",)),
                    OperatorCall("Plan-motion", ("#config1", "#config2"), ("#traj12",)),
                    OperatorCall("Move-Place", ("body", "#traj12")),
                ),
            ),
        )
    )


@dataclass
class AnalyticWorld:
    """A `BindingWorld` whose checks are functions; `checks[(t, c)]` guards call c of layer t."""

    name: str
    skeleton: Skeleton
    checks: dict[tuple[int, int], Check]
    culprit_candidates: tuple[str, ...] = ()
    calls: int = field(default=0)
    geometry: WorldGeometry = field(default_factory=WorldGeometry)

    def initial_state(self) -> object:
        return None

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        self.calls += 1
        results: list[CheckResult] = []
        for position, call in enumerate(self.skeleton.transitions[index].calls):
            check = self.checks.get((index, position))
            culprits = check(bindings) if check is not None else None
            if culprits is None:
                results.append(CheckResult(call, True))
                continue
            reason = "collision" if culprits else "unreachable"
            named = tuple(Culprit(body, 0.01 / (rank + 1)) for rank, body in enumerate(culprits))
            results.append(CheckResult(call, False, reason, named))
            break
        return TransitionOutcome(tuple(results), state=None)


SHELF_CENTRE = (0.65, 0.35)
SHELF_RADIUS = 0.25
MOTION_CLEARANCE_Y = 0.4


def _shelf_reach(bindings: Mapping[str, Value]) -> tuple[str, ...] | None:
    """IK on the shelf: reachable inside a disc in (x, y) (~20% of the square), else the arm
    hits the shelf."""
    x, y, _ = cast(list[float], bindings["#pose12"])
    inside = (x - SHELF_CENTRE[0]) ** 2 + (y - SHELF_CENTRE[1]) ** 2 < SHELF_RADIUS**2
    return None if inside else ("shelf",)


def _shelf_motion(bindings: Mapping[str, Value]) -> tuple[str, ...] | None:
    """The motion to a reachable placement passes only beyond obstacle3 (y >= 0.4): the
    feasible placements are a segment of the disc, ~7% of the square."""
    y = cast(list[float], bindings["#pose12"])[1]
    return None if y >= MOTION_CLEARANCE_Y else ("obstacle3",)


def shelf_reachable(pose: list[float]) -> bool:
    return _shelf_reach({"#pose12": pose}) is None


def shelf_feasible(pose: list[float]) -> bool:
    return shelf_reachable(pose) and _shelf_motion({"#pose12": pose}) is None


def _grasp_blocked(blocked: dict[str, tuple[str, ...]]) -> Check:
    def check(bindings: Mapping[str, Value]) -> tuple[str, ...] | None:
        return blocked.get(str(bindings["#dir1"]))

    return check


def analytic_world(task: str) -> AnalyticWorld:
    """`desk` or `deskP`: both place `body` on the shelf region `region2`."""
    candidates = ("obstacle1", "obstacle2", "obstacle3", "shelf")
    if task == "desk":
        checks = {
            (0, 0): _grasp_blocked({"right": ("obstacle2",), "back": ()}),
            (0, 1): _grasp_blocked({"left": ("obstacle1",)}),
            (1, 0): _shelf_reach,
            (1, 1): _shelf_motion,
        }
        return AnalyticWorld("desk", pick_place_skeleton("pose0", "region2"), checks, candidates)
    if task == "deskP":
        checks = {
            (0, 0): _grasp_blocked({"back": ()}),
            (1, 0): _shelf_reach,
            (1, 1): _shelf_motion,
        }
        return AnalyticWorld("deskP", pick_place_skeleton("poseP", "region2"), checks, candidates)
    raise ValueError(f"unknown analytic task {task!r}: desk or deskP")

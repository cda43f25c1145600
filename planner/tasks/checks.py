"""Geometry that cannot work, found when a task loads, before any rollout.

`impossibility` finds what certainly fails (a body wider than the gripper opens, a start pose
or a goal region beyond the arm's reach, a region narrower than its body): the loader refuses
the task with it. `geometry_warnings` finds what will likely fail (a region the sampler cannot
spread its body in, a place beyond the Panda's stated reach): the task loads, with a warning.
Pure arithmetic on the task's data (no simulator); the numbers follow the simulator's own
rules (`planner.sim.scene.Scene.region_pose`, `planner.sim.grasps.make_grasp`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.tasks.reach import ArmReach, arm_reach
from planner.tasks.schema import (
    Goal,
    LayerSpec,
    MovableBody,
    Region,
    Workspace,
    smaller,
    start_support,
)

PANDA_SHOULDER_HEIGHT = 0.333  # joint 2 above the base, where the arm's reach is measured from
PANDA_REACH = 0.855  # the Panda's stated maximum reach from that joint, metres
FINGER_CLEARANCE = 0.01  # each finger stays this far off the body while open
TOP_GRASP_DEPTH = 0.03  # how far below the top face the fingertips reach
SIDE_GRASP_BELOW_TOP = 0.04  # side grasps centre the fingers this far below the top face


def start_footing(
    workspace: Workspace, bodies: dict[str, MovableBody], name: str
) -> tuple[tuple[float, float], float, float]:
    """Where body `name` starts: its centre's (x, y), its yaw and the height of the surface it
    stands on (a body on another is centred on that one's top face, turned as it is)."""
    body = bodies[name]
    if body.pose in bodies:
        xy, yaw, surface = start_footing(workspace, bodies, body.pose)
        return xy, yaw, surface + bodies[body.pose].size[2]
    pose = workspace.poses[body.pose]
    return pose.xy, pose.yaw, workspace.regions[pose.region].center[2]


def start_region(workspace: Workspace, bodies: dict[str, MovableBody], name: str) -> Region:
    """The region `name`: the workspace's, or the top face of a movable body where it starts
    (`On(body, other_body)` stacks on it; the simulator follows the body if it moves)."""
    if name in workspace.regions:
        return workspace.regions[name]
    body = bodies[name]
    xy, yaw, surface = start_footing(workspace, bodies, name)
    return Region(name, (*xy, surface + body.size[2]), (body.size[0], body.size[1]), yaw)


def _corners(body: MovableBody, xy: tuple[float, float], yaw: float) -> list[tuple[float, float]]:
    return centre_corners(Region(body.name, (*xy, 0.0), (body.size[0], body.size[1]), yaw), 0.0)


def _overlap(a: list[tuple[float, float]], b: list[tuple[float, float]]) -> bool:
    """Whether two rectangles (their corners, as `centre_corners` orders them) overlap by more
    than a millimetre: no axis of either separates them."""
    for rect in (a, b):
        for i, j in ((0, 1), (0, 2)):
            ax, ay = rect[j][0] - rect[i][0], rect[j][1] - rect[i][1]
            norm = math.hypot(ax, ay) or 1.0
            pa = [(x * ax + y * ay) / norm for x, y in a]
            pb = [(x * ax + y * ay) / norm for x, y in b]
            if min(max(pa), max(pb)) - max(min(pa), min(pb)) <= 1e-3:
                return False
    return True


def start_conflict(
    workspace: Workspace, bodies: dict[str, MovableBody], stacking: str
) -> Impossible | None:
    """A start no scene can hold: a body on itself, bodies that stand on each other in a
    circle, two bodies on one body (each is centred on the one below), two whose footprints
    overlap on one surface; with `stacking: towers`, a body on one not larger than itself or
    two towers on one region."""
    for name in bodies:
        chain = [name]
        while bodies[chain[-1]].pose in bodies:
            below = bodies[chain[-1]].pose
            if below == name:
                what = (
                    f"{name} cannot start on itself"
                    if len(chain) == 1
                    else f"{' on '.join([*chain, name])}: the bodies stand on each other in a "
                    "circle, none on a region"
                )
                return Impossible(f"bodies.{name}.pose", what)
            if below in chain:
                break  # a circle above another body's; that body's turn reports it
            chain.append(below)
    above: dict[str, str] = {}
    for name, body in bodies.items():
        if body.pose in bodies:
            other = above.setdefault(body.pose, name)
            if other != name:
                return Impossible(
                    f"bodies.{name}.pose",
                    f"{other} and {name} both start on {body.pose}: a body starting on another "
                    "is centred on its top face, so one body holds one",
                )
            if stacking == "towers" and not smaller(body, bodies[body.pose]):
                return Impossible(
                    f"bodies.{name}.pose",
                    f"{name} starts on {body.pose}, which is not larger: with stacking: towers a "
                    "body stands only on a larger one",
                )
    grounded = [n for n, b in bodies.items() if b.pose not in bodies]
    for i, a in enumerate(grounded):
        for b in grounded[i + 1 :]:
            ra, rb = start_support(workspace, bodies, a), start_support(workspace, bodies, b)
            if stacking == "towers" and ra == rb:
                return Impossible(
                    f"bodies.{b}.pose",
                    f"{a} and {b} both start on {ra}: with stacking: towers a region holds one "
                    "tower",
                )
            fa, fb = start_footing(workspace, bodies, a), start_footing(workspace, bodies, b)
            if abs(fa[2] - fb[2]) < 1e-6 and _overlap(
                _corners(bodies[a], *fa[:2]), _corners(bodies[b], *fb[:2])
            ):
                return Impossible(
                    f"bodies.{b}.pose",
                    f"{b} at {bodies[b].pose} overlaps {a} at {bodies[a].pose}: two bodies "
                    "cannot start in one place",
                )
    return None


def footprint_margin(body: MovableBody) -> float:
    """How far `Sample-pose` keeps the body's centre inside each edge of a region: half the
    longer side of its footprint, whatever the yaw it is placed at."""
    return max(body.size[:2]) / 2


def centre_corners(region: Region, margin: float) -> list[tuple[float, float]]:
    """World (x, y) of the corners of the rectangle the body's centre may take in `region`."""
    half_x = max(0.0, region.size[0] / 2 - margin)
    half_y = max(0.0, region.size[1] / 2 - margin)
    c, s = math.cos(region.yaw), math.sin(region.yaw)
    cx, cy = region.center[0], region.center[1]
    return [
        (cx + c * dx - s * dy, cy + s * dx + c * dy)
        for dx in (-half_x, half_x)
        for dy in (-half_y, half_y)
    ]


def _reach(workspace: Workspace, x: float, y: float, z: float) -> float:
    bx, by, bz = workspace.robot.base
    return math.dist((bx, by, bz + PANDA_SHOULDER_HEIGHT), (x, y, z))


def geometry_warnings(
    workspace: Workspace, bodies: dict[str, MovableBody], layers: tuple[LayerSpec, ...]
) -> tuple[str, ...]:
    """One sentence per placement region that cannot hold its body or leaves the arm's reach,
    and per start pose out of reach (reach is checked for a Panda only)."""
    found: list[str] = []
    panda = "panda" in workspace.robot.urdf.lower()
    placements = dict.fromkeys(
        tuple(c.args) for layer in layers for c in layer.calls if c.name == "Sample-pose"
    )
    for body_name, region_name in placements:
        body, region = bodies[body_name], start_region(workspace, bodies, region_name)
        margin = footprint_margin(body)
        if min(region.size) < 2 * margin:
            found.append(
                f"Sample-pose({body_name}, {region_name}): {region_name} "
                f"({region.size[0]:.3f} x {region.size[1]:.3f} m) cannot hold {body_name} "
                f"({2 * margin:.3f} m along its longer side, placed at any yaw): its centre is "
                "held on the region's middle line and the body overhangs the region"
            )
        if panda:
            z = region.center[2] + body.size[2]
            far = max(_reach(workspace, x, y, z) for x, y in centre_corners(region, margin))
            if far > PANDA_REACH:
                found.append(
                    f"Sample-pose({body_name}, {region_name}): part of {region_name} lies "
                    f"{far:.2f} m from the arm's shoulder, beyond the Panda's {PANDA_REACH} m "
                    "reach"
                )
    for body in bodies.values() if panda else ():
        xy, _, surface = start_footing(workspace, bodies, body.name)
        distance = _reach(workspace, *xy, surface + body.size[2])
        if distance > PANDA_REACH:
            found.append(
                f"{body.name} starts at {body.pose}, {distance:.2f} m from the arm's shoulder, "
                f"beyond the Panda's {PANDA_REACH} m reach"
            )
    return tuple(found)


@dataclass(frozen=True)
class Impossible:
    """What cannot work, and the task file's field it is written in."""

    where: str
    message: str


def max_held_width(workspace: Workspace) -> float:
    """The widest body side the gripper closes across, clearance left on both fingers."""
    return workspace.robot.gripper_opening - 2 * FINGER_CLEARANCE


def _tool_heights(surface: float, body: MovableBody) -> tuple[float, float]:
    """The lowest and highest tool centre of any grasp of `body` standing on `surface`."""
    height = body.size[2]
    top = surface + height - min(TOP_GRASP_DEPTH, height / 2)
    side = surface + height / 2 + max(0.0, height / 2 - SIDE_GRASP_BELOW_TOP)
    return min(top, side), max(top, side)


def _nearest(reach: ArmReach, region: Region, margin: float, heights: tuple[float, float]) -> float:
    """The least distance from the arm's shoulder to a tool centre over the body's centres in
    `region` (its rectangle shrunk by `margin`) at the given heights."""
    half_x = max(0.0, region.size[0] / 2 - margin)
    half_y = max(0.0, region.size[1] / 2 - margin)
    c, s = math.cos(region.yaw), math.sin(region.yaw)
    dx, dy = reach.shoulder[0] - region.center[0], reach.shoulder[1] - region.center[1]
    local_x, local_y = c * dx + s * dy, -s * dx + c * dy
    out_x = max(0.0, abs(local_x) - half_x)
    out_y = max(0.0, abs(local_y) - half_y)
    low, high = heights
    out_z = max(0.0, low - reach.shoulder[2], reach.shoulder[2] - high)
    return math.sqrt(out_x**2 + out_y**2 + out_z**2)


def impossibility(
    workspace: Workspace,
    bodies: dict[str, MovableBody],
    layers: tuple[LayerSpec, ...],
    goals: tuple[Goal, ...],
) -> Impossible | None:
    """The first thing in the task that no binding can make work, or None."""
    reach = arm_reach(workspace.robot)
    robot = workspace.robot.urdf
    grasped = [c.args[0] for layer in layers for c in layer.calls if c.name == "Inv-kin"]
    # A goal-only task moves every body whose goal does not hold where it starts.
    grasped += [g.body for g in goals if start_support(workspace, bodies, g.body) != g.region]
    picked = dict.fromkeys(grasped)
    widest = max_held_width(workspace)
    for name in picked:
        body = bodies[name]
        narrow = min(body.size[:2])
        if narrow > widest:
            return Impossible(
                f"bodies.{name}.size",
                f"{name} is {body.size[0]:.3f} x {body.size[1]:.3f} m across, but the gripper "
                f"opens {workspace.robot.gripper_opening:.3f} m and holds at most {widest:.3f} m "
                f"({FINGER_CLEARANCE} m clear of each finger): no grasp can pick it",
            )
        xy, _, surface = start_footing(workspace, bodies, name)
        start = Region(body.pose, (*xy, surface), (0.0, 0.0))
        distance = _nearest(reach, start, 0.0, _tool_heights(surface, body))
        if distance > reach.bound:
            return Impossible(
                f"bodies.{name}.pose",
                f"{name} starts at {body.pose}, {distance:.2f} m from the arm's shoulder: "
                f"beyond the {reach.bound:.2f} m {robot} reaches at most, no grasp can pick it",
            )
    placements = [
        (f"skeleton[{i}].decision", *layer.calls[0].args)
        for i, layer in enumerate(layers)
        if layer.calls[0].name == "Sample-pose"
    ]
    placements += [(f"goal[{i}]", g.body, g.region) for i, g in enumerate(goals)]
    for where, body_name, region_name in placements:
        body, region = bodies[body_name], start_region(workspace, bodies, region_name)
        if min(body.size[:2]) > min(region.size):
            return Impossible(
                where,
                f"no place in {region.name} ({region.size[0]:.3f} x {region.size[1]:.3f} m) "
                f"fits {body.name}: its narrower side, {min(body.size[:2]):.3f} m, is wider "
                "than the region at any yaw",
            )
    for i, goal in enumerate(goals):
        body, region = bodies[goal.body], start_region(workspace, bodies, goal.region)
        margin = footprint_margin(body)
        distance = _nearest(reach, region, margin, _tool_heights(region.center[2], body))
        if distance > reach.bound:
            return Impossible(
                f"goal[{i}]",
                f"On({goal.body}, {goal.region}): every place in {goal.region} is at least "
                f"{distance:.2f} m from the arm's shoulder, beyond the {reach.bound:.2f} m "
                f"{robot} reaches at most: no operator can put {goal.body} there",
            )
    return None

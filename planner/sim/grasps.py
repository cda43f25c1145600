"""Grasps: a robot-relative direction (front, right, top, back, left) turned into a fixed
gripper pose in the body's frame, and PyBullet IK with seeded restarts for a gripper pose."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p

from planner.sim.geometry import (
    Pose,
    Vec3,
    angle_between,
    compose,
    invert,
    quat_from_axes,
    rotation,
)
from planner.sim.motion import Checker, CollisionTally
from planner.sim.scene import Scene
from planner.tasks import GRASP_APPROACH
from planner.tasks.checks import FINGER_CLEARANCE, SIDE_GRASP_BELOW_TOP, TOP_GRASP_DEPTH

ORIENTATION_TOLERANCE = 0.01  # radians
IK_REFINEMENTS = 4
APPROACH_LIFT = 0.02


@dataclass(frozen=True)
class Grasp:
    """The gripper's TCP pose in the body's frame, the approach axis in the body's frame,
    and the finger opening (per finger) that clears the body."""

    body: str
    direction: str
    tcp_in_body: Pose
    approach_in_body: Vec3
    opening: float


class GraspError(ValueError):
    """A grasp that the gripper cannot make (the body is wider than the gripper opens)."""


def make_grasp(scene: Scene, body: str, direction: str, body_pose: Pose) -> Grasp:
    """The grasp `direction` of `body` standing at `body_pose`, relative to the robot base:
    the gripper comes onto the body face whose outward normal is most against the approach."""
    base = scene.task.workspace.robot.base
    bearing = math.atan2(body_pose[0][1] - base[1], body_pose[0][0] - base[0])
    c, s = math.cos(bearing), math.sin(bearing)
    ax, ay, az = GRASP_APPROACH[direction]
    approach_world = np.array([c * ax - s * ay, s * ax + c * ay, az])
    body_rot = rotation(body_pose[1])
    size = np.asarray(scene.sizes[body])
    # Snap the approach onto one of the body's face normals (its axes, both signs).
    local = body_rot.T @ approach_world
    axis = int(np.argmax(np.abs(local)))
    approach_local = np.zeros(3)
    approach_local[axis] = math.copysign(1.0, local[axis])
    if axis == 2:
        tcp_local = np.array([0.0, 0.0, size[2] / 2 - min(TOP_GRASP_DEPTH, size[2] / 2)])
        # Fingers close across the horizontal body axis most across the bearing.
        bearing_local = body_rot.T @ np.array([c, s, 0.0])
        finger_axis = 0 if abs(bearing_local[0]) < abs(bearing_local[1]) else 1
        y = np.zeros(3)
        y[finger_axis] = 1.0
        z = approach_local
        x = np.cross(y, z)
        if x @ bearing_local < 0:
            y, x = -y, -x
    else:
        # Side grasps hold the upper part of the body, clear of the surface it stands on.
        tcp_local = np.array([0.0, 0.0, max(0.0, size[2] / 2 - SIDE_GRASP_BELOW_TOP)])
        z = approach_local
        y = np.cross(z, body_rot.T @ np.array([0.0, 0.0, 1.0]))
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        finger_axis = int(np.argmax(np.abs(y)))
    width = float(size[finger_axis])
    opening = width / 2 + FINGER_CLEARANCE
    if opening > scene.max_finger_opening:
        raise GraspError(
            f"{body} is {width:.3f} m wide across the fingers; the gripper opens "
            f"{2 * scene.max_finger_opening:.2f} m"
        )
    tcp = ((float(tcp_local[0]), float(tcp_local[1]), float(tcp_local[2])), quat_from_axes(x, y, z))
    return Grasp(body, direction, tcp, tuple(float(v) for v in approach_local), opening)  # type: ignore[arg-type]


def hand_heading(grasp: Grasp) -> float:
    """The heading (radians, about the body's z) in which the hand points in the body's frame:
    the approach of a side grasp, the forward axis of a top grasp's hand. A body placed with yaw
    `theta - hand_heading(grasp)` has the hand pointing at `theta` whichever face it holds."""
    x, y, z = grasp.approach_in_body
    if abs(z) < 0.5:
        return math.atan2(y, x)
    forward = rotation(grasp.tcp_in_body[1])[:, 0]
    return math.atan2(float(forward[1]), float(forward[0]))


def rolled(grasp: Grasp) -> Grasp:
    """The same side grasp with the hand turned half a turn about its approach axis."""
    pos, orn = grasp.tcp_in_body
    r = rotation(orn)
    flipped = quat_from_axes(-r[:, 0], -r[:, 1], r[:, 2])
    return Grasp(grasp.body, grasp.direction, (pos, flipped), grasp.approach_in_body, grasp.opening)


def tcp_target(grasp: Grasp, body_pose: Pose, back_off: float = 0.0) -> Pose:
    """World TCP pose for the grasp of a body at `body_pose`, `back_off` metres back along the
    approach axis (0.1 m gives the pre-grasp) and lifted by APPROACH_LIFT, so that a body
    carried off its support does not scrape it."""
    pos, orn = compose(body_pose, grasp.tcp_in_body)
    if back_off == 0.0:
        return pos, orn
    direction = rotation(body_pose[1]) @ np.asarray(grasp.approach_in_body)
    moved = np.asarray(pos) - back_off * direction + np.array([0.0, 0.0, APPROACH_LIFT])
    moved = tuple(float(v) for v in moved)
    return moved, orn


def carried_pose(scene: Scene, grasp: Grasp) -> Pose:
    """Where a held body is, given the current TCP."""
    return compose(scene.tcp(), invert(grasp.tcp_in_body))


def total_penetration(hits: Sequence[tuple[str, float]]) -> float:
    """The deepest penetration into each body hit, summed over the bodies: a pose that still
    touches one body is closer to free than one that touches two."""
    deepest: dict[str, float] = {}
    for name, depth in hits:
        deepest[name] = max(deepest.get(name, 0.0), depth)
    return sum(deepest.values())


@dataclass(frozen=True)
class IkResult:
    q: tuple[float, ...] | None
    position_error: float
    orientation_error: float
    restarts: int
    in_collision: int = 0  # restarts that reached the pose but collided
    least_depth: float = math.inf  # the least total penetration among those restarts


def solve_ik(
    scene: Scene,
    target: Pose,
    rng: np.random.Generator,
    *,
    restarts: int,
    iterations: int,
    tolerance: float,
    first_guess: tuple[float, ...] | None = None,
    collisions: Checker | None = None,
    tally: CollisionTally | None = None,
) -> IkResult:
    """PyBullet's damped-least-squares IK from `restarts` seeded starts (`first_guess`, then
    alternately near it and anywhere within the joint limits), accepted within `tolerance`
    metres and the joint limits, and free of collision under `collisions` (the bodies hit are
    added to `tally`). A failure reports the least residuals and the least total
    penetration of the restarts that reached the pose: bookkeeping only, the draws stay those of
    the seed."""
    low, high = np.asarray(scene.joint_low), np.asarray(scene.joint_high)
    best_pos, best_ang = math.inf, math.inf
    reached = 0
    least_depth = math.inf  # bookkeeping only: draws nothing, so the restarts stay as seeded
    link_target = scene.tool_link_target(target)
    for attempt in range(restarts):
        if attempt == 0 and first_guess is not None:
            start = first_guess
        elif first_guess is not None and attempt % 2 == 1:
            start = tuple(
                np.clip(np.asarray(first_guess) + rng.normal(0.0, 0.5, low.size), low, high)
            )
        else:
            start = tuple(rng.uniform(low, high))
        scene.set_arm(start)
        previous = math.inf
        # PyBullet's IK stops short of its own iteration count, so refine from its answer a few
        # times, projecting onto the joint limits in between.
        for _ in range(IK_REFINEMENTS):
            solution = p.calculateInverseKinematics(
                scene.robot,
                scene.tool_link,
                link_target[0],
                link_target[1],
                maxNumIterations=iterations,
                residualThreshold=tolerance / 10,
                physicsClientId=scene.client,
            )
            q = tuple(float(v) for v in np.clip(solution[: len(scene.arm_joints)], low, high))
            scene.set_arm(q)
            error = math.dist(scene.tcp()[0], target[0])
            # Stop when converged, or when a refinement no longer halves the error (stuck
            # against a joint limit or out of reach): more calls would not get there.
            if error < tolerance / 10 or error > previous / 2:
                break
            previous = error
        pos, orn = scene.tcp()
        pos_err = float(np.linalg.norm(np.subtract(pos, target[0])))
        ang_err = angle_between(orn, target[1])
        best_pos, best_ang = min(best_pos, pos_err), min(best_ang, ang_err)
        if pos_err > tolerance or ang_err > ORIENTATION_TOLERANCE or not scene.within_limits(q):
            continue
        hits = collisions(q) if collisions is not None else ()
        if not hits:
            return IkResult(q, pos_err, ang_err, attempt + 1)
        reached += 1
        least_depth = min(least_depth, total_penetration(hits))
        if tally is not None:
            tally.add(hits)
    return IkResult(None, best_pos, best_ang, restarts, reached, least_depth)

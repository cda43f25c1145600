"""The transition operators of a skeleton, executed in a `Scene`: Inv-kin, Plan-motion,
Move-Pick, Move-Place. Each returns a `CheckResult` that says why it failed: the IK error,
the bodies in collision (most often first, with the deepest penetration), or the planner's
timeout. Cheap checks run before expensive ones: IK and its collision check before any
motion planning."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from contract.models import Value
from planner.sim.geometry import Pose, derived_seed, quat_from_axes, rotation
from planner.sim.grasps import (
    Grasp,
    GraspError,
    IkResult,
    carried_pose,
    hand_heading,
    make_grasp,
    rolled,
    solve_ik,
    tcp_target,
)
from planner.sim.motion import Checker, CollisionTally, check_segment, rrt_connect
from planner.sim.scene import Scene
from planner.skeleton import OperatorCall
from planner.tasks.schema import PlannerSettings
from planner.world import PROGRESS_CAP, CheckResult, Culprit


@dataclass(frozen=True)
class ArmConfig:
    """A robot configuration produced by Inv-kin: the grasp config, its approach config
    (0.1 m back along the approach axis), the grasp it makes and where the body then stands."""

    q: tuple[float, ...]
    pre: tuple[float, ...] | None = None
    grasp: Grasp | None = None
    body_pose: Pose | None = None
    region: str | None = None


@dataclass(frozen=True)
class Trajectory:
    """Joint-space waypoints; consecutive ones are joined by checked straight segments."""

    waypoints: tuple[tuple[float, ...], ...]
    goal: ArmConfig
    carrying: str | None


@dataclass
class Execution:
    """The mutable state of one transition layer being executed."""

    scene: Scene
    settings: PlannerSettings
    seed: int
    bindings: Mapping[str, Value]
    pose_sources: Mapping[str, tuple[str, str]]  # '#pose12' -> (body, region)
    values: dict[str, object]
    arm: tuple[float, ...]
    held: Grasp | None
    tally: CollisionTally = field(default_factory=CollisionTally)
    attempt: int = 0

    def draw_seed(self, call: OperatorCall, *inputs: object) -> int:
        """The seed of a randomised check: a function of the run's seed, the check's inputs and
        every binding on the tree path, so it gives the same verdict whatever the search did
        before it, yet a check whose inputs no decision changes (picking a body where it
        starts) draws afresh on every new branch instead of repeating one unlucky IK solution
        for the whole run; and of the attempt, so a repeated attempt draws afresh too."""
        path = tuple(sorted(self.bindings.items()))
        extra = (self.attempt,) if self.attempt else ()
        return derived_seed(self.seed, _text(call), *inputs, path, *extra)

    def checker(self) -> Checker:
        """Collisions of the arm at q, carrying the held body along."""
        scene, held = self.scene, self.held

        def hits(q: tuple[float, ...]) -> list[tuple[str, float]]:
            scene.set_arm(q)
            if held is not None:
                scene.set_pose(held.body, carried_pose(scene, held))
            contacts = scene.contacts(held.body if held is not None else None)
            return [(c.other, c.depth) for c in contacts]

        return hits

    def settle(self) -> None:
        """Put the arm (and the held body) back where the execution says they are."""
        self.scene.set_arm(self.arm)
        if self.held is not None:
            self.scene.set_fingers(self.held.opening)
            self.scene.set_pose(self.held.body, carried_pose(self.scene, self.held))

    def culprits(self) -> tuple[Culprit, ...]:
        found = []
        for name, _, depth in self.tally.ranked():
            pose = None
            if name in self.scene.ids:
                pos, orn = self.scene.pose(name)
                pose = (*pos, *orn)
            found.append(Culprit(body=name, depth=depth, pose=pose))
        return tuple(found)

    def collision_text(self) -> str:
        return ", ".join(
            f"{name} ({count}x, {depth * 1000:.1f} mm deep)"
            for name, count, depth in self.tally.ranked()[:3]
        )


def _text(call: OperatorCall) -> str:
    out = f" -> {', '.join(call.outputs)}" if call.outputs else ""
    return f"{call.name}({', '.join(call.args)}){out}"


def _fail(
    call: OperatorCall, ex: Execution, reason: str, *, conclusive: bool = True, **detail: float
) -> CheckResult:
    return CheckResult(
        call, False, f"{_text(call)}: {reason}", ex.culprits(), detail, conclusive=conclusive
    )


# How far a failed Inv-kin got, as `progress` in [0, 1): its stage (the grasp pose out of reach,
# reached only in collision, then the same two for the approach pose), plus a closeness within
# the stage. The search does not use it; MCTS-BO regresses on it, to tell apart children that
# failed at the same check (`planner.search.pwuct.PWUCT._graded_depth`).
IK_OUT_OF_REACH, IK_COLLIDES, APPROACH_OUT_OF_REACH, APPROACH_COLLIDES = range(4)
IK_STAGES = 4
REACH_SCALE = 0.05  # metres of IK residual at which reach closeness is one half
DEPTH_SCALE = 0.01  # metres of total penetration at which collision closeness is one half
METRES_PER_RADIAN = 0.1  # an orientation residual counted as a position residual
PROGRESS_STEP = 1e-3  # progress is rounded to this: penetrations differ by solver noise


def ik_progress(stage: int, tried: list[IkResult]) -> float:
    """`(stage + closeness) / IK_STAGES`, rounded to `PROGRESS_STEP`; closeness
    `1 / (1 + residual / REACH_SCALE)` for a pose out of reach, `1 / (1 + least total
    penetration / DEPTH_SCALE)` for a pose reached only in collision (the restart that came
    closest to being free: the deepest penetration over restarts is noisy)."""
    if stage in (IK_OUT_OF_REACH, APPROACH_OUT_OF_REACH):
        residual = min(r.position_error + METRES_PER_RADIAN * r.orientation_error for r in tried)
        closeness = 1.0 / (1.0 + residual / REACH_SCALE)
    else:
        closeness = 1.0 / (1.0 + min(r.least_depth for r in tried) / DEPTH_SCALE)
    progress = round((stage + closeness) / IK_STAGES / PROGRESS_STEP) * PROGRESS_STEP
    return min(progress, PROGRESS_CAP)


# A failed Plan-motion's `progress`: which of its three parts failed (no closeness within).
MOTION_RETREAT, MOTION_PATH, MOTION_APPROACH = range(3)
MOTION_STAGES = 3


def first_guess(scene: Scene, target: Pose) -> tuple[float, ...]:
    """A start for IK that is already close: a nominal solution for the same kind of hand pose
    straight ahead of the robot (hand pointing down, or level with its x axis up or down),
    with the base joint turned toward the target."""
    nominal = scene.nominal_ik
    if not nominal:
        rng = np.random.default_rng(0)
        for kind, z, x in (("down", (0, 0, -1), (1, 0, 0)), ("up", (1, 0, 0), (0, 0, 1))):
            for sign in (1.0, -1.0) if kind == "up" else (1.0,):
                xa, za = np.asarray(x, float) * sign, np.asarray(z, float)
                pose = ((0.5, 0.0, 0.15), quat_from_axes(xa, np.cross(za, xa), za))
                solved = solve_ik(scene, pose, rng, restarts=200, iterations=100, tolerance=1e-3)
                nominal[(kind, sign)] = solved.q or tuple(scene.task.workspace.robot.home)
    axes = rotation(target[1])
    key = ("down", 1.0) if axes[2, 2] < -0.7 else ("up", 1.0 if axes[2, 0] >= 0 else -1.0)
    guess = list(nominal[key])
    bearing = math.atan2(target[0][1], target[0][0])
    guess[0] = float(np.clip(guess[0] + bearing, *scene.joint_range(0)))
    return tuple(guess)


def _body_pose(ex: Execution, body: str, pose_arg: str) -> tuple[Pose, str]:
    """Where `pose_arg` puts `body`: a held body by the hand's heading (`Scene.region_pose`);
    a body already standing at a decided pose, where it actually stands."""
    if pose_arg.startswith("#"):
        owner, region = ex.pose_sources[pose_arg]
        seed = ex.bindings[pose_arg]
        if ex.held is not None and ex.held.body == owner:
            heading = hand_heading(ex.held)
            return ex.scene.region_pose(owner, region, seed, heading), region  # type: ignore[arg-type]
        position, _ = ex.scene.region_pose(owner, region, seed)  # type: ignore[arg-type]
        return (position, ex.scene.pose(owner)[1]), region
    return ex.scene.named_pose(pose_arg, body), ex.scene.pose_region(pose_arg)


def inv_kin(call: OperatorCall, ex: Execution) -> CheckResult:
    body, pose_arg, grasp_arg = call.args
    scene, s = ex.scene, ex.settings
    body_pose, region = _body_pose(ex, body, pose_arg)
    if ex.held is not None:
        if ex.held.body != body:
            return _fail(call, ex, f"the gripper holds {ex.held.body}, not {body}")
        candidates = [ex.held]
    else:
        here = scene.pose(body)[0]
        if math.dist(here, body_pose[0]) > 1e-4:
            return _fail(call, ex, f"{body} is not at {pose_arg}")
        direction = str(ex.bindings[grasp_arg]) if grasp_arg.startswith("#") else grasp_arg
        try:
            grasp = make_grasp(scene, body, direction, body_pose)
        except GraspError as exc:
            return _fail(call, ex, str(exc))
        scene.set_fingers(grasp.opening)
        # A side grasp can be made with the hand either way up.
        candidates = [grasp] if direction == "top" else [grasp, rolled(grasp)]
    check = ex.checker()
    rng = np.random.default_rng(ex.draw_seed(call, body_pose, candidates[0].direction))
    options: dict[str, Any] = dict(
        restarts=s.ik_restarts,
        iterations=s.ik_iterations,
        tolerance=s.ik_tolerance,
    )
    tried: list[IkResult] = []
    for grasp in candidates:
        target = tcp_target(grasp, body_pose)
        found = solve_ik(
            scene,
            target,
            rng,
            collisions=check,
            tally=ex.tally,
            first_guess=first_guess(scene, target),
            **options,
        )
        tried.append(found)
        if found.q is not None:
            break
    if found.q is None:
        ex.settle()
        if ex.tally.counts:  # some restart reached the pose, but in collision
            return _fail(
                call,
                ex,
                f"every IK solution collides with {ex.collision_text()}",
                conclusive=False,
                least_depth=min(r.least_depth for r in tried),
                progress=ik_progress(IK_COLLIDES, tried),
            )
        return _fail(
            call,
            ex,
            f"no IK solution for the {grasp.direction} grasp of {body} within {s.ik_tolerance} m "
            f"in {found.restarts} restarts (best error {found.position_error:.3f} m, "
            f"{found.orientation_error:.2f} rad)",
            conclusive=False,
            position_error=found.position_error,
            orientation_error=found.orientation_error,
            progress=ik_progress(IK_OUT_OF_REACH, tried),
        )
    approach = tcp_target(grasp, body_pose, s.approach)
    pre = solve_ik(
        scene, approach, rng, collisions=check, tally=ex.tally, first_guess=found.q, **options
    )
    ex.settle()
    if pre.q is None:
        if ex.tally.counts:
            what = f"collides with {ex.collision_text()}"
        else:
            what = f"is out of reach (best error {pre.position_error:.3f} m)"
        stage = APPROACH_COLLIDES if pre.in_collision else APPROACH_OUT_OF_REACH
        return _fail(
            call,
            ex,
            f"the approach pose {s.approach} m back {what}",
            conclusive=False,
            position_error=pre.position_error,
            least_depth=pre.least_depth,
            progress=ik_progress(stage, [pre]),
        )
    ex.values[call.outputs[0]] = ArmConfig(found.q, pre.q, grasp, body_pose, region)
    return CheckResult(call, True, detail={"ik_restarts": float(found.restarts + pre.restarts)})


def plan_motion(call: OperatorCall, ex: Execution) -> CheckResult:
    start, goal = (ex.values[a] for a in call.args)
    assert isinstance(start, ArmConfig) and isinstance(goal, ArmConfig)
    s = ex.settings
    if ex.held is None:
        openings = [c.grasp.opening for c in (start, goal) if c.grasp is not None]
        ex.scene.set_fingers(max(openings, default=ex.scene.fingers()))
    check = ex.checker()
    a = start.pre if start.pre is not None else start.q
    b = goal.pre if goal.pre is not None else goal.q
    if start.pre is not None and not check_segment(
        start.q, a, check, s.motion_resolution, ex.tally
    ):
        ex.settle()
        return _fail(
            call,
            ex,
            f"the retreat from {call.args[0]} collides with {ex.collision_text()}",
            progress=MOTION_RETREAT / MOTION_STAGES,
        )
    seed = ex.draw_seed(call, a, b)
    middle, checks = rrt_connect(
        a,
        b,
        check,
        low=ex.scene.joint_low,
        high=ex.scene.joint_high,
        seed=seed,
        max_checks=s.motion_max_checks,
        timeout=s.motion_timeout,
        resolution=s.motion_resolution,
        tally=ex.tally,
    )
    if middle is None:
        ex.settle()
        hit = f"; states in collision with {ex.collision_text()}" if ex.tally.counts else ""
        return _fail(
            call,
            ex,
            f"RRT-Connect found no path within its budget of {s.motion_max_checks} collision "
            f"checks ({checks} used){hit}",
            conclusive=False,
            collision_checks=float(checks),
            progress=MOTION_PATH / MOTION_STAGES,
        )
    if goal.pre is not None and not check_segment(b, goal.q, check, s.motion_resolution, ex.tally):
        ex.settle()
        return _fail(
            call,
            ex,
            f"the approach to {call.args[1]} collides with {ex.collision_text()}",
            conclusive=False,
            progress=MOTION_APPROACH / MOTION_STAGES,
        )
    ex.settle()
    waypoints = (start.q, *middle, goal.q)
    carrying = ex.held.body if ex.held is not None else None
    ex.values[call.outputs[0]] = Trajectory(waypoints, goal, carrying)
    detail = {"waypoints": float(len(waypoints)), "collision_checks": float(checks)}
    return CheckResult(call, True, detail=detail)


def move_pick(call: OperatorCall, ex: Execution) -> CheckResult:
    body, traj_var = call.args
    traj = ex.values[traj_var]
    assert isinstance(traj, Trajectory)
    if ex.held is not None:
        return _fail(call, ex, f"the gripper already holds {ex.held.body}")
    grasp = traj.goal.grasp
    if grasp is None or grasp.body != body:
        return _fail(call, ex, f"{traj_var} does not end at a grasp of {body}")
    ex.arm = traj.waypoints[-1]
    ex.held = grasp
    ex.settle()
    return CheckResult(call, True)


def move_place(call: OperatorCall, ex: Execution) -> CheckResult:
    body, traj_var = call.args
    traj = ex.values[traj_var]
    assert isinstance(traj, Trajectory)
    if ex.held is None or ex.held.body != body:
        return _fail(call, ex, f"the gripper does not hold {body}")
    ex.arm = traj.waypoints[-1]
    ex.settle()
    ex.held = None
    region = traj.goal.region
    if region is not None and not ex.scene.in_region(body, region):
        return _fail(call, ex, f"{body} does not stand in {region}")
    return CheckResult(call, True)


OPERATORS = {
    "Inv-kin": inv_kin,
    "Plan-motion": plan_motion,
    "Move-Pick": move_pick,
    "Move-Place": move_place,
}

"""A task's scene in one PyBullet client: the arm, static bodies, movable bodies, collisions.

The client id lives on the `Scene` object; nothing here is global. Collision queries run
PyBullet's broadphase once (`performCollisionDetection`) and read every contact at once.
"""

from __future__ import annotations

import math
import os
import sys
import weakref
from collections.abc import Iterable
from dataclasses import dataclass

import pybullet as p
import pybullet_data

from planner.sim.geometry import Pose, compose, invert, yaw_of, yaw_quat
from planner.tasks.reach import arm_joint_names
from planner.tasks.schema import FixedBody, NamedPose, Region, Task

PLACE_CLEARANCE = 0.001  # a placed body floats 1 mm above its support, as the authors do


class GuiUnavailable(RuntimeError):
    """A GUI was asked for where there is no display."""


@dataclass(frozen=True)
class Contact:
    """A penetrating contact between the robot or the held body and another body."""

    other: str
    depth: float


class Scene:
    """Bodies of one task in one PyBullet client (DIRECT unless `gui`)."""

    def __init__(self, task: Task, *, gui: bool = False) -> None:
        self.task = task
        if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            # PyBullet ends the whole process when it cannot reach an X server.
            raise GuiUnavailable("PyBullet's window needs a display, and DISPLAY is not set")
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        # A client lives until disconnected (about 90 MB with the Panda), whatever happens to this
        # object: disconnect when the scene is collected, also after a failed __init__ below.
        self._disconnect = weakref.finalize(self, _disconnect, self.client)
        self.gui = gui
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=self.client)
        ws = task.workspace
        flags = p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS
        self.robot = p.loadURDF(
            ws.robot.urdf,
            basePosition=ws.robot.base,
            useFixedBase=True,
            flags=flags,
            physicsClientId=self.client,
        )
        infos = [
            p.getJointInfo(self.robot, j, physicsClientId=self.client)
            for j in range(p.getNumJoints(self.robot, physicsClientId=self.client))
        ]
        by_joint = {info[1].decode(): info[0] for info in infos}
        # The loader checked that the URDF has the tool link and `home` a value per arm joint.
        self.arm_joints = tuple(by_joint[name] for name in arm_joint_names(ws.robot))
        self.tool_link = next(info[0] for info in infos if info[12].decode() == ws.robot.tool_link)
        self.tool_offset: Pose = (ws.robot.tool_offset, (0.0, 0.0, 0.0, 1.0))
        # Prismatic fingers are set to the opening a grasp needs; a gripper of revolute
        # linkages (the xArm's) stays fully open, the held body carried by the tool frame.
        self.finger_joints = tuple(
            info[0]
            for info in infos
            if info[2] == p.JOINT_PRISMATIC and info[0] not in self.arm_joints
        )
        # Everything beyond the last arm joint (flange, hand, fingers) may touch a held body.
        self.hand_links = tuple(range(self.arm_joints[-1] + 1, len(infos)))
        self.joint_low = [infos[j][8] for j in self.arm_joints]
        self.joint_high = [infos[j][9] for j in self.arm_joints]
        self.max_finger_opening = ws.robot.gripper_opening / 2  # each finger's travel
        self.names: dict[int, str] = {self.robot: "robot"}
        self.ids: dict[str, int] = {}
        statics = [*ws.fixed.values(), *(ws.obstacles[n] for n in task.obstacles)]
        for body in statics:
            self._add_static(body)
        self.static_names = tuple(b.name for b in statics)
        self.sizes: dict[str, tuple[float, float, float]] = {}
        for movable in task.bodies.values():
            half = [s / 2 for s in movable.size]
            shape = p.createCollisionShape(
                p.GEOM_BOX, halfExtents=half, physicsClientId=self.client
            )
            visual = p.createVisualShape(
                p.GEOM_BOX, halfExtents=half, rgbaColor=movable.color, physicsClientId=self.client
            )
            # Non-zero mass so PyBullet reports its contacts with static bodies; never stepped.
            uid = p.createMultiBody(0.2, shape, visual, physicsClientId=self.client)
            self._register(movable.name, uid)
            self.sizes[movable.name] = movable.size
        self.movable_names = tuple(task.bodies)
        self.start_poses()
        # Nominal IK solutions by kind of hand pose, filled on first use (planner.sim.operators).
        self.nominal_ik: dict[tuple[str, float], tuple[float, ...]] = {}

    def _register(self, name: str, uid: int) -> None:
        self.ids[name] = uid
        self.names[uid] = name

    def _add_static(self, body: FixedBody) -> None:
        n = len(body.parts)
        shapes = dict(
            shapeTypes=[p.GEOM_BOX] * n,
            halfExtents=[[s / 2 for s in part.size] for part in body.parts],
            collisionFramePositions=[part.offset for part in body.parts],
        )
        collision = p.createCollisionShapeArray(**shapes, physicsClientId=self.client)
        visual = p.createVisualShapeArray(
            shapeTypes=shapes["shapeTypes"],
            halfExtents=shapes["halfExtents"],
            visualFramePositions=shapes["collisionFramePositions"],
            rgbaColors=[body.color] * n,
            physicsClientId=self.client,
        )
        uid = p.createMultiBody(
            0,
            collision,
            visual,
            basePosition=body.position,
            baseOrientation=yaw_quat(body.yaw),
            physicsClientId=self.client,
        )
        self._register(body.name, uid)

    # -- poses -----------------------------------------------------------------------------
    def region(self, name: str) -> Region:
        """A workspace region, or the top face of a movable body where it stands now."""
        if name not in self.sizes:
            return self.task.workspace.regions[name]
        (x, y, z), orn = self.pose(name)
        size_x, size_y, height = self.sizes[name]
        return Region(name, (x, y, z + height / 2), (size_x, size_y), yaw_of(orn))

    def standing_pose(self, body: str, region: Region, x: float, y: float, yaw: float) -> Pose:
        z = region.center[2] + self.sizes[body][2] / 2 + PLACE_CLEARANCE
        return (x, y, z), yaw_quat(yaw)

    def named_pose(self, pose: str, body: str) -> Pose:
        """A workspace's named pose, or the pose on top of movable body `pose` where it stands
        now: centred on its top face, turned as it is."""
        if pose in self.sizes:
            top = self.region(pose)
            return self.standing_pose(body, top, top.center[0], top.center[1], top.yaw)
        named: NamedPose = self.task.workspace.poses[pose]
        return self.standing_pose(body, self.region(named.region), *named.xy, named.yaw)

    def pose_region(self, pose: str) -> str:
        """The region a named pose stands on: the workspace's, or the body it names."""
        return pose if pose in self.sizes else self.task.workspace.poses[pose].region

    def start_poses(self) -> tuple[tuple[str, Pose], ...]:
        """Put every movable body where the task starts it, each body before those standing
        on it (the loader refused circles), and give those poses in `movable_names` order."""
        bodies = self.task.bodies
        placed: dict[str, Pose] = {}

        def place(name: str) -> None:
            if name in placed:
                return
            if bodies[name].pose in bodies:
                place(bodies[name].pose)
            placed[name] = self.named_pose(bodies[name].pose, name)
            self.set_pose(name, placed[name])

        for name in self.movable_names:
            place(name)
        return tuple((name, placed[name]) for name in self.movable_names)

    def region_pose(
        self, body: str, region_name: str, seed: Iterable[float], heading: float = 0.0
    ) -> Pose:
        """Map a seed in [0,1]^3 to a standing pose in the region, as the authors do: x and y in
        the region's box shrunk by half the body's footprint, yaw in [-pi, pi]. The yaw is that
        of the frame `heading` turns the body's frame by: a held body is placed by the hand's
        heading (see `grasps.hand_heading`), so that the feasible yaws of every grasp, and of
        every face the hand holds, are one band of the seed, and knowledge about one transfers
        to the others."""
        sx, sy, syaw = (min(1.0, max(0.0, float(v))) for v in seed)
        region = self.region(region_name)
        half_x, half_y = self.placement_extents(body, region_name)
        local = ((2 * sx - 1) * half_x, (2 * sy - 1) * half_y, 0.0)
        frame = ((region.center[0], region.center[1], 0.0), yaw_quat(region.yaw))
        (x, y, _), _ = compose(frame, (local, (0.0, 0.0, 0.0, 1.0)))
        yaw = region.yaw + (2 * syaw - 1) * math.pi - heading
        return self.standing_pose(body, region, x, y, yaw)

    def placement_extents(self, body: str, region_name: str) -> tuple[float, float]:
        """The half extents in metres that `region_pose` spans about the region's centre: the
        region's half size less half the body's footprint (any yaw keeps it inside)."""
        region = self.region(region_name)
        margin = max(self.sizes[body][:2]) / 2
        return max(0.0, region.size[0] / 2 - margin), max(0.0, region.size[1] / 2 - margin)

    def in_region(self, body: str, region_name: str, tolerance: float = 3e-3) -> bool:
        region = self.region(region_name)
        pos, _ = self.pose(body)
        frame = ((region.center[0], region.center[1], 0.0), yaw_quat(region.yaw))
        (lx, ly, _), _ = compose(invert(frame), (pos, (0.0, 0.0, 0.0, 1.0)))
        bottom = pos[2] - self.sizes[body][2] / 2
        return (
            abs(lx) <= region.size[0] / 2 + tolerance
            and abs(ly) <= region.size[1] / 2 + tolerance
            and abs(bottom - region.center[2] - PLACE_CLEARANCE) <= tolerance
        )

    def pose(self, name: str) -> Pose:
        pos, orn = p.getBasePositionAndOrientation(self.ids[name], physicsClientId=self.client)
        return tuple(pos), tuple(orn)

    def set_pose(self, name: str, pose: Pose) -> None:
        p.resetBasePositionAndOrientation(
            self.ids[name], pose[0], pose[1], physicsClientId=self.client
        )

    # -- robot -----------------------------------------------------------------------------
    def set_arm(self, q: Iterable[float]) -> None:
        # One call for all seven joints: five times faster than resetJointState per joint, and
        # the arm is set once per collision check.
        values = [[float(v)] for v in q]
        if len(values) != len(self.arm_joints):
            raise ValueError(f"expected {len(self.arm_joints)} joint values, got {len(values)}")
        p.resetJointStatesMultiDof(
            self.robot, list(self.arm_joints), values, physicsClientId=self.client
        )

    def arm(self) -> tuple[float, ...]:
        states = p.getJointStates(self.robot, self.arm_joints, physicsClientId=self.client)
        return tuple(s[0] for s in states)

    def set_fingers(self, opening: float) -> None:
        for j in self.finger_joints:
            p.resetJointState(self.robot, j, opening, physicsClientId=self.client)

    def fingers(self) -> float:
        if not self.finger_joints:
            return self.max_finger_opening
        return p.getJointState(self.robot, self.finger_joints[0], physicsClientId=self.client)[0]

    def tcp(self) -> Pose:
        state = p.getLinkState(
            self.robot, self.tool_link, computeForwardKinematics=True, physicsClientId=self.client
        )
        link: Pose = (tuple(state[4]), tuple(state[5]))
        return compose(link, self.tool_offset)

    def tool_link_target(self, tcp: Pose) -> Pose:
        """Where the tool link must be for the tool centre point to be at `tcp` (what IK
        solves for)."""
        return compose(tcp, invert(self.tool_offset))

    def joint_range(self, index: int) -> tuple[float, float]:
        return self.joint_low[index], self.joint_high[index]

    def within_limits(self, q: Iterable[float]) -> bool:
        return all(
            lo - 1e-6 <= v <= hi + 1e-6
            for v, lo, hi in zip(q, self.joint_low, self.joint_high, strict=True)
        )

    # -- collisions ------------------------------------------------------------------------
    def contacts(self, held: str | None = None) -> list[Contact]:
        """Penetrations of the robot (self-collision included) and of the held body; contacts
        between a held body and the gripper holding it do not count."""
        p.performCollisionDetection(physicsClientId=self.client)
        found: list[Contact] = []
        held_id = self.ids[held] if held is not None else None
        for cp in p.getContactPoints(physicsClientId=self.client):
            depth = -cp[8]
            if depth <= 0.0:
                continue
            a, b = cp[1], cp[2]
            if self.robot not in (a, b) and held_id not in (a, b):
                continue
            if {a, b} == {self.robot, held_id}:
                link = cp[3] if a == self.robot else cp[4]
                if link in self.hand_links:
                    continue
            if a == b == self.robot:
                # The hand's own links touching each other is its mechanism (the xArm's
                # gripper linkage), not a collision.
                if not (cp[3] in self.hand_links and cp[4] in self.hand_links):
                    found.append(Contact("robot", depth))
                continue
            mover = a if a in (self.robot, held_id) else b
            other = b if mover == a else a
            found.append(Contact(self.names.get(other, str(other)), depth))
        return found

    def close(self) -> None:
        self._disconnect()


def _disconnect(client: int) -> None:
    if p.isConnected(client):
        p.disconnect(client)

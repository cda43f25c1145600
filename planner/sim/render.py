"""Pictures of a scene (PyBullet's TinyRenderer, no display needed) and replays of a binding."""

from __future__ import annotations

import itertools
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p

from contract.models import Value
from planner.sim.geometry import yaw_quat
from planner.sim.grasps import carried_pose
from planner.sim.motion import interpolate
from planner.sim.operators import Trajectory
from planner.sim.world import PyBulletWorld, SimState
from planner.world import TransitionOutcome

REGION_COLOR = (0.2, 0.8, 0.2, 0.35)


@dataclass(frozen=True)
class Camera:
    """PyBullet's orbit camera: `yaw` and `pitch` in degrees (pitch below 0 looks down),
    `distance` in metres from `target`, the point looked at (world frame)."""

    yaw: float
    pitch: float
    distance: float
    target: tuple[float, float, float]


def mark_regions(world: PyBulletWorld) -> None:
    """Thin, visual-only plates on the regions the task's skeleton names (no collision shape)."""
    scene = world.scene
    named = {a for layer in world.skeleton.layers for c in layer.calls for a in c.args}
    for name, region in scene.task.workspace.regions.items():
        if name not in named:
            continue
        visual = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=[region.size[0] / 2, region.size[1] / 2, 0.0005],
            rgbaColor=REGION_COLOR,
            physicsClientId=scene.client,
        )
        center = (region.center[0], region.center[1], region.center[2] + 0.0006)
        p.createMultiBody(
            0,
            -1,
            visual,
            basePosition=center,
            baseOrientation=yaw_quat(region.yaw),
            physicsClientId=scene.client,
        )


def snapshot(
    world: PyBulletWorld,
    path: Path,
    *,
    width: int = 960,
    height: int = 720,
    camera: Camera | None = None,
) -> None:
    """Write a PNG of the scene as it stands, seen from `camera`, by default from behind and
    above the robot."""
    import matplotlib.image

    client = world.scene.client
    if camera is None:
        view = p.computeViewMatrix(
            cameraEyePosition=[-0.55, 0.75, 1.05],
            cameraTargetPosition=[0.5, -0.05, 0.05],
            cameraUpVector=[0, 0, 1],
            physicsClientId=client,
        )
    else:
        view = p.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=list(camera.target),
            distance=camera.distance,
            yaw=camera.yaw,
            pitch=camera.pitch,
            roll=0.0,
            upAxisIndex=2,
            physicsClientId=client,
        )
    projection = p.computeProjectionMatrixFOV(
        fov=45, aspect=width / height, nearVal=0.05, farVal=5.0, physicsClientId=client
    )
    _, _, rgba, _, _ = p.getCameraImage(
        width,
        height,
        view,
        projection,
        renderer=p.ER_TINY_RENDERER,
        physicsClientId=client,
    )
    image = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3]
    matplotlib.image.imsave(path, image)


def replay(
    world: PyBulletWorld, bindings: Mapping[str, Value], *, delay: float = 0.0
) -> list[TransitionOutcome]:
    """Execute the transitions a binding reaches, in order, stopping at the first failure; with
    `delay` > 0 each trajectory is shown step by step (for the GUI)."""
    state: SimState = world.initial_state()
    outcomes = []
    for index in range(len(world.skeleton.transitions)):
        needed = [d.var for d in world.skeleton.decisions[: index + 1]]
        if any(v not in bindings for v in needed):
            break
        before = state
        outcome = world.transition(index, bindings, state)
        outcomes.append(outcome)
        if delay > 0:
            _animate(world, before, outcome, delay)
        if not outcome.ok:
            break
        assert isinstance(outcome.state, SimState)
        state = outcome.state
    return outcomes


def _animate(
    world: PyBulletWorld, before: SimState, outcome: TransitionOutcome, delay: float
) -> None:
    """Show the trajectories of a successful transition layer, waypoint by waypoint."""
    if not isinstance(outcome.state, SimState):
        return
    scene = world.scene
    values = dict(outcome.state.values)
    world.restore(before)
    held = before.held
    for check in outcome.checks:
        if check.call.name not in ("Move-Pick", "Move-Place"):
            continue
        trajectory = values[check.call.args[1]]
        assert isinstance(trajectory, Trajectory)
        for a, b in itertools.pairwise(trajectory.waypoints):
            for q in interpolate(a, b, 0.02):
                scene.set_arm(q)
                if held is not None:
                    scene.set_pose(held.body, carried_pose(scene, held))
                time.sleep(delay)
        held = trajectory.goal.grasp if check.call.name == "Move-Pick" else None
    world.restore(outcome.state)

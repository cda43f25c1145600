"""Geometry that loads but cannot work: a region too small for its body, a place out of reach.

Pure arithmetic on the task's data (no simulator), so that `load_task` can report it at once;
the numbers follow the simulator's own rules (`planner.sim.scene.Scene.region_pose`).
"""

from __future__ import annotations

import math

from planner.tasks.schema import LayerSpec, MovableBody, Region, Workspace

PANDA_SHOULDER_HEIGHT = 0.333  # joint 2 above the base, where the arm's reach is measured from
PANDA_REACH = 0.855  # the Panda's stated maximum reach from that joint, metres


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
        body, region = bodies[body_name], workspace.regions[region_name]
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
        pose = workspace.poses[body.pose]
        z = workspace.regions[pose.region].center[2] + body.size[2]
        distance = _reach(workspace, *pose.xy, z)
        if distance > PANDA_REACH:
            found.append(
                f"{body.name} starts at {body.pose}, {distance:.2f} m from the arm's shoulder, "
                f"beyond the Panda's {PANDA_REACH} m reach"
            )
    return tuple(found)

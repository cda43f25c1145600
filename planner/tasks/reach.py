"""How far an arm can reach at most, read from its URDF without a simulator.

The bound is the triangle inequality along the joint chain: from the origin of the first
movable joint (fixed in the world, whatever the joints do) to the tool link, no configuration
puts the tool farther than the sum of the joint offsets (plus the stroke of any prismatic
joint). It is loose but sound, so a place beyond it is certainly out of reach: the load-time
checks (`planner.tasks.checks`) refuse such a task rather than warn about it.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet_data

from planner.tasks.schema import RobotSpec, TaskError, Vec3


@dataclass(frozen=True)
class ArmReach:
    """The tool cannot leave the ball of radius `bound` about `shoulder` (in the robot's base
    frame: a robot on the table with its base unturned, as every workspace places it)."""

    shoulder: Vec3
    bound: float


def urdf_path(urdf: str) -> Path:
    """The URDF file a workspace names: a path inside pybullet_data, or an absolute path."""
    path = Path(urdf)
    return path if path.is_absolute() else Path(pybullet_data.getDataPath()) / path


def _origin(joint: ElementTree.Element, key: str) -> Vec3:
    origin = joint.find("origin")
    text = origin.get(key, "0 0 0") if origin is not None else "0 0 0"
    x, y, z = (float(v) for v in text.split())
    return x, y, z


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


@functools.cache
def _chain(urdf: str, tool_link: str) -> tuple[tuple[str, Vec3, Vec3, float, str], ...]:
    """The joints from the root link to `tool_link`: (type, origin offset, origin roll-pitch-
    yaw, prismatic stroke, name)."""
    path = urdf_path(urdf)
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError) as exc:
        raise TaskError(f"cannot read the robot's URDF {urdf} ({exc})") from None
    # Direct children only: a <transmission> holds <joint> elements of its own.
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}  # type: ignore[union-attr]
    links = {link.get("name") for link in root.findall("link")}
    if tool_link not in links:
        raise TaskError(f"{urdf} has no link {tool_link!r}")
    chain = []
    link = tool_link
    while link in by_child:
        joint = by_child[link]
        limit = joint.find("limit")
        stroke = 0.0
        if joint.get("type") == "prismatic" and limit is not None:
            stroke = abs(float(limit.get("upper", 0))) + abs(float(limit.get("lower", 0)))
        kind = joint.get("type", "fixed")
        name = joint.get("name", "")
        chain.append((kind, _origin(joint, "xyz"), _origin(joint, "rpy"), stroke, name))
        parent = joint.find("parent")
        link = parent.get("link", "") if parent is not None else ""
    return tuple(reversed(chain))


def arm_reach(robot: RobotSpec) -> ArmReach:
    """The ball the robot's tool frame stays in (see the module docstring)."""
    chain = _chain(robot.urdf, robot.tool_link)
    first = next((i for i, link in enumerate(chain) if link[0] != "fixed"), len(chain))
    # The joints up to the first movable one are rigid: their origins place the shoulder.
    position, turn = np.asarray(robot.base, dtype=float), np.eye(3)
    for _, offset, rpy, _, _ in chain[: first + 1]:
        position = position + turn @ np.asarray(offset)
        turn = turn @ _rpy_matrix(*rpy)
    bound = sum(math.hypot(*offset) + stroke for _, offset, _, stroke, _ in chain[first + 1 :])
    bound += math.hypot(*robot.tool_offset)
    x, y, z = (float(v) for v in position)
    return ArmReach((x, y, z), bound)


def arm_joint_names(robot: RobotSpec) -> tuple[str, ...]:
    """The movable joints from the base to the tool link, in order: the arm's, which `home`
    gives one value each."""
    return tuple(name for kind, *_, name in _chain(robot.urdf, robot.tool_link) if kind != "fixed")

"""The validated, in-memory form of a task file and of the workspace it lives in.

Pure data (no PyBullet): the loader builds these from YAML, the simulator builds a scene from
them. Lengths are metres, angles in the files are degrees and radians here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]


class TaskError(ValueError):
    """A task or workspace file with a mistake; the message names the file and the field."""


@dataclass(frozen=True)
class BoxPart:
    """A box of `size` (full extents) centred at `offset` in its owner's frame."""

    size: Vec3
    offset: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class FixedBody:
    """A static body (table, shelf, obstacle): one or more boxes at `position`, turned by `yaw`."""

    name: str
    position: Vec3
    yaw: float
    parts: tuple[BoxPart, ...]
    color: tuple[float, float, float, float]


@dataclass(frozen=True)
class Region:
    """A rectangle on a support surface: centre (x, y, top z), full size (x, y), turned by yaw."""

    name: str
    center: Vec3
    size: tuple[float, float]
    yaw: float = 0.0


@dataclass(frozen=True)
class NamedPose:
    """A fixed body pose on a region: x, y and yaw; z follows from the body standing on it."""

    name: str
    region: str
    xy: tuple[float, float]
    yaw: float


@dataclass(frozen=True)
class RobotSpec:
    """The arm: its URDF (in pybullet_data or an absolute path), where its base stands, its
    home configuration (`config0`, one value per joint from the base to the tool link), the
    tool centre point between the fingertips (`tool_offset` along the axes of `tool_link`'s
    frame), and how wide its gripper opens (metres, between the fingers)."""

    urdf: str
    base: Vec3
    home: tuple[float, ...]
    tool_link: str
    gripper_opening: float
    tool_offset: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class PlannerSettings:
    """Simulator settings that trade thoroughness for rollout time."""

    ik_restarts: int = 8
    ik_iterations: int = 100
    ik_tolerance: float = 1e-3
    motion_max_checks: int = 4000  # RRT-Connect's budget, in collision checks (deterministic)
    motion_timeout: float = 5.0  # seconds; a safety net only
    motion_resolution: float = 0.05
    approach: float = 0.1


@dataclass(frozen=True)
class Workspace:
    name: str
    robot: RobotSpec
    fixed: dict[str, FixedBody]
    obstacles: dict[str, FixedBody]
    regions: dict[str, Region]
    poses: dict[str, NamedPose]


@dataclass(frozen=True)
class MovableBody:
    """A movable box. `pose` is a named pose of the workspace, or the name of another movable
    body that this one starts on (centred on its top face, turned as it is)."""

    name: str
    size: Vec3
    pose: str
    color: tuple[float, float, float, float]


STACKING = ("free", "towers")  # what the symbolic domain allows to stand on what


def start_support(workspace: Workspace, bodies: dict[str, MovableBody], name: str) -> str:
    """Where body `name` starts: the region of its named pose, or the body it stands on."""
    pose = bodies[name].pose
    return pose if pose in bodies else workspace.poses[pose].region


def smaller(a: MovableBody, b: MovableBody) -> bool:
    """Whether `a`'s footprint fits within `b`'s, side for side (shorter within shorter, longer
    within longer) and strictly smaller: what `stacking: towers` lets stand on `b`."""
    a_short, a_long = sorted(a.size[:2])
    b_short, b_long = sorted(b.size[:2])
    return a_short < b_short and a_long < b_long


@dataclass(frozen=True)
class Call:
    """One operator call as written: `name(args...) -> outputs`."""

    name: str
    args: tuple[str, ...]
    outputs: tuple[str, ...]


@dataclass(frozen=True)
class LayerSpec:
    kind: str
    calls: tuple[Call, ...]


@dataclass(frozen=True)
class Goal:
    """`On(body, region)`: the body ends standing inside the region."""

    predicate: str
    body: str
    region: str


@dataclass(frozen=True)
class Task:
    name: str
    description: str
    source: str
    workspace: Workspace
    obstacles: tuple[str, ...]
    bodies: dict[str, MovableBody]
    layers: tuple[LayerSpec, ...]
    goal: tuple[Goal, ...]
    settings: PlannerSettings = field(default_factory=PlannerSettings)
    # Tasks run into the knowledge base before this one by `cp-bo-transfer`, in order: shipped
    # names as written, task files as resolved paths (what `load_task` and `run_plan` accept).
    predecessors: tuple[str, ...] = ()
    role: str | None = None  # "target" or "predecessor": how a suite directory is read
    kind: str | None = None  # a free label (desk, regrasp, pack) to group a suite's results
    warnings: tuple[str, ...] = ()  # geometry that loads but will not work (see loader)
    # "towers": a body stacks only on a larger one and a region holds one body (Hanoi's rules);
    # "free": anything clear holds anything, a region any number side by side.
    stacking: str = "free"

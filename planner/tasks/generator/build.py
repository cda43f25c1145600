"""One generated workspace and its tasks, as the dictionaries written to YAML.

The workspace holds every obstacle, region and pose of its tasks (names are workspace-wide,
so a constraint met in a predecessor has the same name in its target). Each target gets its
own predecessors, which stand among the target's obstacles but move another body, from
another start, or to another region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planner.tasks.generator.layout import (
    GAP,
    Body,
    Cubby,
    Floor,
    Rect,
    Start,
    draw_cubby,
    draw_spot,
    draw_start,
    grid_poses,
    local_to_world,
)

ROBOT = {
    "urdf": "franka_panda/panda.urdf",
    "base": [0.0, 0.0, 0.0],
    "home": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
}
OBSTACLE_COLOR = [0.3, 0.45, 0.8, 1.0]
BODY_COLORS = (
    [0.95, 0.55, 0.1, 1.0],
    [0.9, 0.3, 0.3, 1.0],
    [0.3, 0.8, 0.3, 1.0],
    [0.3, 0.4, 0.9, 1.0],
)


def _r(v: float) -> float:
    return round(float(v), 4)


def _deg(rad: float) -> float:
    return round(math.degrees(rad), 2)


@dataclass
class WorkspaceDraft:
    """The workspace file under construction."""

    name: str
    fixed: dict[str, Any] = field(default_factory=dict)
    obstacles: dict[str, Any] = field(default_factory=dict)
    regions: dict[str, Any] = field(default_factory=dict)
    poses: dict[str, Any] = field(default_factory=dict)

    def box(self, name: str, rect: Rect, height: float, base: float = 0.0) -> None:
        self.obstacles[name] = {
            "position": [_r(rect.x), _r(rect.y), _r(base + height / 2)],
            "yaw": _deg(rect.yaw),
            "size": [_r(rect.sx), _r(rect.sy), _r(height)],
            "color": OBSTACLE_COLOR,
        }

    def region(self, name: str, rect: Rect, z: float = 0.0) -> None:
        self.regions[name] = {
            "center": [_r(rect.x), _r(rect.y), _r(z)],
            "size": [_r(rect.sx), _r(rect.sy)],
            "yaw": _deg(rect.yaw),
        }

    def pose(self, name: str, region: str, rect: Rect) -> None:
        self.poses[name] = {"region": region, "xy": [_r(rect.x), _r(rect.y)], "yaw": _deg(rect.yaw)}

    def to_yaml(self) -> dict[str, Any]:
        return {
            "workspace": self.name,
            "robot": ROBOT,
            "fixed": self.fixed,
            "obstacles": self.obstacles,
            "regions": self.regions,
            "poses": self.poses,
        }


def add_table_and_cubby(ws: WorkspaceDraft, cubby: Cubby) -> None:
    depth, width = cubby.outer.sx - 0.04, cubby.outer.sy - 0.04
    bt, top = cubby.board_top, cubby.board_top + cubby.clearance
    wall = top + 0.02
    ws.fixed["table"] = {
        "position": [0.55, 0.0, -0.025],
        "size": [0.8, 1.4, 0.05],
        "color": [0.75, 0.65, 0.5, 1.0],
    }
    parts = [
        ([depth, width, 0.02], [0.0, 0.0, bt - 0.01]),
        ([depth, 0.02, wall], [0.0, width / 2 + 0.01, wall / 2]),
        ([depth, 0.02, wall], [0.0, -width / 2 - 0.01, wall / 2]),
        ([0.02, width + 0.04, wall], [depth / 2 + 0.01, 0.0, wall / 2]),
        ([depth, width + 0.04, 0.02], [0.0, 0.0, top + 0.01]),
    ]
    ws.fixed["shelf"] = {
        "position": [_r(cubby.outer.x), _r(cubby.outer.y), 0.0],
        "yaw": _deg(cubby.outer.yaw),
        "color": [0.55, 0.4, 0.3, 1.0],
        "parts": [{"size": [_r(v) for v in s], "offset": [_r(v) for v in o]} for s, o in parts],
    }
    ws.region("region_shelf", cubby.region, bt)
    ws.box("shelf_box", cubby.obstacle, cubby.obstacle_height, bt)


def add_tray(ws: WorkspaceDraft, tray: Rect, wall: float) -> None:
    sx, sy = tray.sx - 0.02, tray.sy - 0.02  # the interior
    parts = [
        ([0.01, sy + 0.02, wall], [sx / 2 + 0.005, 0.0]),
        ([0.01, sy + 0.02, wall], [-sx / 2 - 0.005, 0.0]),
        ([sx, 0.01, wall], [0.0, sy / 2 + 0.005]),
        ([sx, 0.01, wall], [0.0, -sy / 2 - 0.005]),
    ]
    ws.obstacles["tray"] = {
        "position": [_r(tray.x), _r(tray.y), 0.0],
        "yaw": _deg(tray.yaw),
        "color": [0.4, 0.6, 0.4, 1.0],
        "parts": [
            {"size": [_r(v) for v in s], "offset": [_r(o[0]), _r(o[1]), _r(wall / 2)]}
            for s, o in parts
        ],
    }
    ws.region("region_tray", Rect(tray.x, tray.y, sx, sy, tray.yaw))


def body_entry(body: Body, pose: str, color_index: int = 0) -> dict[str, Any]:
    return {"size": list(body.size), "pose": pose, "color": BODY_COLORS[color_index % 4]}


def pick_place_layers(body: str, start: str, region: str, n: int = 1) -> list[dict[str, Any]]:
    """Grasp at a named pose, place in a region (the shipped desk's skeleton)."""
    return [
        {"decision": f"Sample-grasp({body}) -> #dir{n}"},
        {
            "transition": [
                f"Inv-kin({body}, {start}, #dir{n}) -> #config{n}",
                f"Plan-motion(config0, #config{n}) -> #traj0{n}",
                f"Move-Pick({body}, #traj0{n})",
            ]
        },
        {"decision": f"Sample-pose({body}, {region}) -> #pose{n}2"},
        {
            "transition": [
                f"Inv-kin({body}, #pose{n}2, #dir{n}) -> #config{n}2",
                f"Plan-motion(#config{n}, #config{n}2) -> #traj{n}2",
                f"Move-Place({body}, #traj{n}2)",
            ]
        },
    ]


def regrasp_layers(start: str, middle: str, goal: str) -> list[dict[str, Any]]:
    """Pick, put down in `middle`, grasp again, place in `goal` (the shipped regrasp's)."""
    return [
        {"decision": "Sample-grasp(body) -> #dir1"},
        {
            "transition": [
                f"Inv-kin(body, {start}, #dir1) -> #config1",
                "Plan-motion(config0, #config1) -> #traj01",
                "Move-Pick(body, #traj01)",
            ]
        },
        {"decision": f"Sample-pose(body, {middle}) -> #pose13"},
        {
            "transition": [
                "Inv-kin(body, #pose13, #dir1) -> #config3",
                "Plan-motion(#config1, #config3) -> #traj13",
                "Move-Place(body, #traj13)",
            ]
        },
        {"decision": "Sample-grasp(body) -> #dir2"},
        {
            "transition": [
                "Inv-kin(body, #pose13, #dir2) -> #config4",
                "Plan-motion(#config3, #config4) -> #traj34",
                "Move-Pick(body, #traj34)",
            ]
        },
        {"decision": f"Sample-pose(body, {goal}) -> #pose12"},
        {
            "transition": [
                "Inv-kin(body, #pose12, #dir2) -> #config2",
                "Plan-motion(#config4, #config2) -> #traj42",
                "Move-Place(body, #traj42)",
            ]
        },
    ]


def pack_layers(bodies: list[str], region: str) -> list[dict[str, Any]]:
    """Top grasps, one box after the other into `region` (the shipped pack's)."""
    layers: list[dict[str, Any]] = []
    previous = "config0"
    for name in bodies:
        i = name.removeprefix("body")
        layers += [
            {"decision": f"Sample-pose({name}, {region}) -> #pose{i}"},
            {
                "transition": [
                    f"Inv-kin({name}, pose_src{i}, top) -> #config{i}1",
                    f"Plan-motion({previous}, #config{i}1) -> #traj{i}1",
                    f"Move-Pick({name}, #traj{i}1)",
                    f"Inv-kin({name}, #pose{i}, top) -> #config{i}2",
                    f"Plan-motion(#config{i}1, #config{i}2) -> #traj{i}2",
                    f"Move-Place({name}, #traj{i}2)",
                ]
            },
        ]
        previous = f"#config{i}2"
    return layers


@dataclass(frozen=True)
class Shared:
    """What the desk-like and regrasp-like tasks of one workspace stand among."""

    floor: Floor
    cubby: Cubby
    start: Start
    alt: Rect


def draw_shared(rng: np.random.Generator, ws: WorkspaceDraft) -> Shared:
    """The cubby on one side, the cluttered start corner on the other, a free start."""
    side = float(rng.choice([-1.0, 1.0]))
    floor = Floor()
    cubby = draw_cubby(rng, side, floor)
    start = draw_start(rng, -side, floor)
    if not free_area(rng, floor, ws):
        raise RuntimeError("no room for a free area")
    alt = draw_spot(rng, floor, (0.09, 0.09), (-70, 70), (0.3, 0.5), 30)
    if alt is None:
        raise RuntimeError("no room for a free start")
    add_table_and_cubby(ws, cubby)
    ws.region("region_start", Rect(start.pose.x, start.pose.y, 0.2, 0.2, start.pose.yaw))
    ws.pose("pose_start", "region_start", start.pose)
    for side_name, (rect, height) in start.clutter.items():
        ws.box(f"clutter_{side_name}", rect, height)
    ws.region("region_alt", Rect(alt.x, alt.y, 0.2, 0.2, alt.yaw))
    ws.pose("pose_alt", "region_alt", alt)
    return Shared(floor, cubby, start, alt)


def free_area(rng: np.random.Generator, floor: Floor, ws: WorkspaceDraft) -> bool:
    """A free table area for the regrasp, with a box beside it; False when none fits."""
    for _ in range(50):
        size = tuple(rng.uniform(0.15, 0.22, size=2))
        area = draw_spot(rng, Floor([*floor.taken]), size, (-35, 35), (0.3, 0.48))
        if area is None:
            continue
        ob = rng.uniform(0.07, 0.12, size=2)
        side = rng.choice([-1, 1])
        dy = side * (area.sy / 2 + ob[1] / 2 + GAP + 0.002)
        x, y = local_to_world(area, rng.uniform(-0.3, 0.3) * area.sx, dy)
        rect = Rect(x, y, ob[0], ob[1], area.yaw)
        if Floor([*floor.taken, area]).free(rect):
            floor.take(area)
            floor.take(rect)
            ws.region("region_free", area)
            ws.box("free_box", rect, float(rng.uniform(0.1, 0.16)))
            return True
    return False


def pack_area(rng: np.random.Generator, cubby: Cubby, n: int, ws: WorkspaceDraft) -> bool:
    """The source poses of `n` boxes and a tray that holds them snugly; False when none fits."""
    for _ in range(50):
        floor = Floor([cubby.outer])
        rows = math.ceil(n / 2)
        source = draw_spot(rng, floor, (0.1 * rows, 0.1 * min(n, 2)), (-60, 60), (0.33, 0.48), 15)
        if source is None:
            continue
        margins = 0.06 + 0.01  # the largest footprint side, plus a gap
        area = n * margins**2 * rng.uniform(1.8, 2.8)
        aspect = rng.uniform(1.0, 1.8)
        sx = max(math.sqrt(area * aspect), 0.12)
        sy = max(area / sx, 0.12)
        tray = draw_spot(rng, floor, (sx + 0.02, sy + 0.02), (-45, 45), (0.45, 0.62), 25)
        if tray is None:
            continue
        ws.region("region_src", Rect(source.x, source.y, source.sx, source.sy, source.yaw))
        for i, rect in enumerate(grid_poses(source, [Body((0.06, 0.06, 0.1))] * n), start=1):
            ws.pose(f"pose_src{i}", "region_src", rect)
        add_tray(ws, tray, float(rng.uniform(0.03, 0.06)))
        return True
    return False

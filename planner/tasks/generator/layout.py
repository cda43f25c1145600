"""Random tabletop geometry: a cubby, a cluttered start, a free area, a tray, bodies.

Everything is drawn from one numpy `Generator` in the robot's base frame (x forward, y to the
robot's left, table top at z = 0) and kept where the Panda reaches. Footprints are rectangles;
a new one is redrawn until it overlaps none placed before it, so that every task built from a
layout starts collision-free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

TABLE_X = (0.15, 0.95)
TABLE_Y = (-0.7, 0.7)
REACH_XY = (0.3, 0.7)  # distance of a footprint's centre from the base, table height
BODY_SIDE = (0.035, 0.06)  # the gripper opens 0.08 m and keeps 1 cm off each face
BODY_HEIGHT = (0.1, 0.2)
GAP = 0.012  # least free space between two footprints
DRAWS = 200


@dataclass(frozen=True)
class Rect:
    """A footprint: centre, full size along its own axes, yaw (radians)."""

    x: float
    y: float
    sx: float
    sy: float
    yaw: float = 0.0

    def corners(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * [self.sx / 2, self.sy / 2]
        return local @ np.array([[c, s], [-s, c]]) + [self.x, self.y]

    def grown(self, by: float) -> Rect:
        return Rect(self.x, self.y, self.sx + 2 * by, self.sy + 2 * by, self.yaw)


def overlap(a: Rect, b: Rect) -> bool:
    """Separating-axis test of two rectangles."""
    ca, cb = a.corners(), b.corners()
    for rect in (a, b):
        for angle in (rect.yaw, rect.yaw + math.pi / 2):
            axis = np.array([math.cos(angle), math.sin(angle)])
            pa, pb = ca @ axis, cb @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def polar(distance: float, bearing: float) -> tuple[float, float]:
    return distance * math.cos(bearing), distance * math.sin(bearing)


def local_to_world(origin: Rect, dx: float, dy: float) -> tuple[float, float]:
    c, s = math.cos(origin.yaw), math.sin(origin.yaw)
    return origin.x + c * dx - s * dy, origin.y + s * dx + c * dy


@dataclass
class Floor:
    """The footprints taken so far on the table."""

    taken: list[Rect] = field(default_factory=list)

    def free(self, rect: Rect) -> bool:
        corners = rect.corners()
        inside = (
            corners[:, 0].min() >= TABLE_X[0] + 0.02
            and corners[:, 0].max() <= TABLE_X[1] - 0.02
            and corners[:, 1].min() >= TABLE_Y[0] + 0.02
            and corners[:, 1].max() <= TABLE_Y[1] - 0.02
        )
        return inside and not any(
            overlap(rect.grown(GAP / 2), t.grown(GAP / 2)) for t in self.taken
        )

    def take(self, rect: Rect) -> Rect:
        self.taken.append(rect)
        return rect


@dataclass(frozen=True)
class Body:
    size: tuple[float, float, float]


def draw_body(rng: np.random.Generator, height: tuple[float, float] = BODY_HEIGHT) -> Body:
    """A box with a rectangular footprint the gripper can hold across either side."""
    w, d = rng.uniform(*BODY_SIDE, size=2)
    return Body((round(float(w), 3), round(float(d), 3), round(float(rng.uniform(*height)), 3)))


@dataclass(frozen=True)
class Cubby:
    """A shelf board under a top board, between side walls, open toward the robot."""

    outer: Rect  # footprint of the whole cubby; its x axis points from the opening inward
    board_top: float
    clearance: float
    region: Rect
    obstacle: Rect
    obstacle_height: float


def draw_cubby(rng: np.random.Generator, side: float, floor: Floor) -> Cubby:
    for _ in range(DRAWS):
        depth, width = rng.uniform(0.22, 0.30), rng.uniform(0.30, 0.40)
        bearing = side * math.radians(rng.uniform(25, 60))
        x, y = polar(rng.uniform(0.5, 0.62), bearing)
        yaw = bearing + math.radians(rng.uniform(-15, 15))
        outer = Rect(x, y, depth + 0.04, width + 0.04, yaw)
        if not floor.free(outer):
            continue
        region = Rect(x, y, depth - rng.uniform(0.06, 0.1), width - rng.uniform(0.1, 0.16), yaw)
        # A box on the board, in the back half, on one side: the shelf's own clutter.
        ox, oy = (
            rng.uniform(0.3, 0.7) * region.sx / 2,
            rng.choice([-1, 1]) * rng.uniform(0.3, 0.7) * (region.sy / 2),
        )
        side_o = rng.uniform(0.04, 0.07)
        clearance = rng.uniform(0.22, 0.30)
        obstacle = Rect(*local_to_world(region, ox, oy), side_o, side_o, yaw)
        height = min(rng.uniform(0.08, 0.16), clearance - 0.05)
        floor.take(outer)
        return Cubby(outer, rng.uniform(0.02, 0.14), clearance, region, obstacle, height)
    raise RuntimeError("no room for a cubby")


SIDES = {"left": math.pi / 2, "back": 0.0, "right": -math.pi / 2}


@dataclass(frozen=True)
class Start:
    """A start pose with a box beside it on each of the robot's left, back and right."""

    pose: Rect  # the body's own footprint at the pose; yaw is the body's yaw
    clutter: dict[str, tuple[Rect, float]]  # side -> (footprint, height)


def draw_start(rng: np.random.Generator, side: float, floor: Floor) -> Start:
    """Room for any body the generator draws (its half-diagonal, turned any way)."""
    reach = math.hypot(BODY_SIDE[1], BODY_SIDE[1]) / 2
    for _ in range(DRAWS):
        bearing = side * math.radians(rng.uniform(15, 45))
        x, y = polar(rng.uniform(0.42, 0.56), bearing)
        yaw = bearing + math.radians(rng.uniform(-30, 30))
        pose = Rect(x, y, 2 * reach, 2 * reach, yaw)
        clutter = {}
        for name, turn in SIDES.items():
            sx, sy = rng.uniform(0.07, 0.13, size=2)
            spacing = reach + max(sx, sy) / 2 + rng.uniform(0.008, 0.035)
            cx, cy = x + spacing * math.cos(bearing + turn), y + spacing * math.sin(bearing + turn)
            rect = Rect(cx, cy, sx, sy, bearing + math.radians(rng.uniform(-20, 20)))
            clutter[name] = (rect, float(rng.uniform(0.08, 0.18)))
        rects = [pose, *(r for r, _ in clutter.values())]
        if all(floor.free(r) for r in rects) and not any(
            overlap(a, b) for i, a in enumerate(rects) for b in rects[i + 1 :]
        ):
            for r in rects:
                floor.take(r)
            return Start(pose, clutter)
    raise RuntimeError("no room for the start corner")


def draw_spot(
    rng: np.random.Generator,
    floor: Floor,
    size: tuple[float, float],
    bearing: tuple[float, float],
    distance: tuple[float, float],
    yaw_spread: float = 20.0,
) -> Rect | None:
    """A free footprint of `size` at a bearing and distance (degrees, metres) from the base."""
    for _ in range(DRAWS):
        b = math.radians(rng.uniform(*bearing))
        x, y = polar(rng.uniform(*distance), b)
        rect = Rect(x, y, size[0], size[1], b + math.radians(rng.uniform(-yaw_spread, yaw_spread)))
        if floor.free(rect) and REACH_XY[0] <= math.hypot(x, y) <= REACH_XY[1]:
            return floor.take(rect)
    return None


def grid_poses(area: Rect, bodies: list[Body]) -> list[Rect]:
    """Start footprints side by side along the area's axes, one per body."""
    n = len(bodies)
    cols = 2 if n > 2 else n
    rows = math.ceil(n / cols)
    poses = []
    for i, body in enumerate(bodies):
        r, c = divmod(i, cols)
        dx = (r - (rows - 1) / 2) * area.sx / rows
        dy = (c - (cols - 1) / 2) * area.sy / cols
        x, y = local_to_world(area, dx, dy)
        poses.append(Rect(x, y, body.size[0], body.size[1], area.yaw))
    return poses

"""Tight packing, the first kind of the hard family: 5 to 8 boxes of mixed sizes into a tray whose
usable area they cover by 45 % or more, with top grasps, shortest first: the hand is 0.2 m wide
across its fingers and holds a box 3 cm below its top, so a box taller than the one carried
beside its slot would stop the hand (the order the generator chooses, so that a packing exists).

The tray is sized around a packing the generator lays out itself: the boxes in columns along the
tray's x axis (the robot's radial direction, in which the hand points), a finger's room between
columns (a top grasp's fingers close across the bearing, along the tray's y axis) and a few
millimetres between neighbours of one column. The packing is then played in the simulator, box
by box (`witness`): a target is kept only if the whole binding it gives passes every check, so
each target is solvable by construction, whatever the probes find.

The tray's usable area for its boxes is its floor less each box's finger room (`usable_area`): a
top grasp's finger goes down beside one face across the closing axis, so no box as tall stands
within a finger's room of that face (the tray's walls are lower than the fingertips, so they take
none). Counted on the whole floor instead, 45 % leaves no method room to search (BENCHMARKS.md,
"Hard problems").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from planner.tasks.generator.build import WorkspaceDraft, add_tray, body_entry, pack_layers
from planner.tasks.generator.layout import Body, Floor, Rect, draw_spot, local_to_world

BODIES = (5, 8)  # how many boxes a target packs
SIDES = (0.035, 0.06)  # footprint sides: the gripper opens 0.08 m and keeps 1 cm off each face
HEIGHTS = (0.1, 0.2)
FILL = (0.45, 0.52)  # the share of the tray's usable area the boxes cover
# A finger's room: its clearance and the fingertip's 1.43 cm across the closing axis (the Panda's
# collision mesh, over the 3.4 cm the fingertips reach beside a held box).
FINGER_ROOM = 0.024
COLUMN_GAP = 0.032  # between columns: a finger, its clearance, a margin
ROW_GAP = 0.006  # between neighbours of one column
WALL_GAP = 0.006  # between the outer boxes and the tray's walls
PRE_FIRST = 3  # the first predecessor packs this many redrawn boxes, the second the rest
YAW_SEEDS = 8  # the yaw seeds the witness tries per box, a quarter turn apart at every second
ALIGNED = 0.02  # radians: how far a placed box may turn from the tray's axes in the witness


@dataclass(frozen=True)
class Packing:
    """The tray's interior (size along its own x and y) and each box's slot centre in it."""

    size: tuple[float, float]
    slots: tuple[tuple[float, float], ...]  # in the tray's frame, in the order of `bodies`
    fill: float  # the share of the usable area the boxes cover
    floor_fill: float  # the share of the whole floor


def finger_room(bodies: list[Body]) -> float:
    """The floor the boxes' fingers take: a finger's room along one face of each box, its
    shorter side (the least the hand needs, whichever way it closes)."""
    return FINGER_ROOM * sum(min(b.size[:2]) for b in bodies)


def usable_area(size: tuple[float, float], bodies: list[Body]) -> float:
    """The tray's floor less the room the boxes' fingers take."""
    return size[0] * size[1] - finger_room(bodies)


def draw_bodies(rng: np.random.Generator, n: int) -> list[Body]:
    """`n` boxes, small and large mixed, shortest first (the order they are packed in)."""
    bodies = [
        Body(
            (
                round(float(rng.uniform(*SIDES)), 3),
                round(float(rng.uniform(*SIDES)), 3),
                round(float(rng.uniform(*HEIGHTS)), 3),
            )
        )
        for _ in range(n)
    ]
    return sorted(bodies, key=lambda b: b.size[2])


def _columns(bodies: list[Body], columns: int) -> list[list[int]]:
    """The boxes in `columns` columns of near-equal length, the longest placed first."""
    members: list[list[int]] = [[] for _ in range(columns)]
    for i in sorted(range(len(bodies)), key=lambda i: -bodies[i].size[0]):
        shortest = min(
            range(columns), key=lambda c: sum(bodies[j].size[0] + ROW_GAP for j in members[c])
        )
        members[shortest].append(i)
    return members


def _extent(bodies: list[Body], members: list[list[int]]) -> tuple[float, float]:
    """The packing's size along the tray's x and y, walls' gaps included."""
    length = max(sum(bodies[i].size[0] for i in c) + ROW_GAP * (len(c) - 1) for c in members)
    width = sum(max(bodies[i].size[1] for i in c) for c in members)
    return length + 2 * WALL_GAP, width + COLUMN_GAP * (len(members) - 1) + 2 * WALL_GAP


def lay_out(rng: np.random.Generator, bodies: list[Body]) -> Packing | None:
    """Columns of boxes with room for the fingers between them (as many columns as cover the
    floor best), the tray grown to a fill of its usable area drawn between the least and what
    the packing allows (None when the packing itself covers less than the least fill)."""
    n = len(bodies)
    covered = sum(b.size[0] * b.size[1] for b in bodies)
    options = [_columns(bodies, k) for k in (2, 3) if k < n]
    members = max(options, key=lambda m: covered / math.prod(_extent(bodies, m)))
    sx, sy = _extent(bodies, members)
    tightest = covered / usable_area((sx, sy), bodies)
    if tightest < FILL[0]:
        return None
    fill = float(rng.uniform(FILL[0], min(FILL[1], tightest)))
    for column in members:
        rng.shuffle(column)
    grow = math.sqrt((covered / fill + finger_room(bodies)) / (sx * sy))
    size = (sx * grow, sy * grow)
    widths = [max(bodies[i].size[1] for i in column) for column in members]
    slots: list[tuple[float, float]] = [(0.0, 0.0)] * n
    y = -size[1] / 2 + WALL_GAP * grow
    spread_y = (size[1] - sy) / max(len(members) - 1, 1)
    for column, width in zip(members, widths, strict=True):
        length = sum(bodies[i].size[0] for i in column) + ROW_GAP * (len(column) - 1)
        x = -length / 2
        for i in column:
            slots[i] = (round(x + bodies[i].size[0] / 2, 4), round(y + width / 2, 4))
            x += bodies[i].size[0] + ROW_GAP
        y += width + COLUMN_GAP + spread_y
    rounded = (round(size[0], 4), round(size[1], 4))
    return Packing(
        rounded, tuple(slots), covered / usable_area(rounded, bodies), covered / math.prod(rounded)
    )


# Start poses come in pairs along the bearing, a pair alone in its keep-out: the hand is 0.2 m
# wide across its fingers (the bearing's normal), and a taller box beside the one picked would
# stop it; along the bearing it spans only its fingers' and palm's few centimetres.
SOURCE_KEEP_OUT = (0.22, 0.2)  # along the bearing, across it
PAIR_SPACING = 0.11


def place_tray_and_sources(
    rng: np.random.Generator, ws: WorkspaceDraft, packing: Packing, n: int
) -> Rect | None:
    """The tray (its x axis near the bearing, so the hand points along it) and the boxes'
    start poses; None when the table has no room for them."""
    floor = Floor()
    tray = draw_spot(
        rng, floor, (packing.size[0] + 0.02, packing.size[1] + 0.02), (-40, 40), (0.45, 0.6), 8
    )
    if tray is None:
        return None
    for pair in range(math.ceil(n / 2)):
        spot = draw_spot(rng, floor, SOURCE_KEEP_OUT, (-90, 90), (0.34, 0.68), 10)
        if spot is None:
            return None
        members = [i for i in (2 * pair + 1, 2 * pair + 2) if i <= n]
        ws.region(f"region_src{pair + 1}", Rect(spot.x, spot.y, 0.2, 0.1, spot.yaw))
        for k, i in enumerate(members):
            dx = (k - (len(members) - 1) / 2) * PAIR_SPACING
            at = Rect(*local_to_world(spot, dx, 0.0), 0.06, 0.06, spot.yaw)
            ws.pose(f"pose_src{i}", f"region_src{pair + 1}", at)
    add_tray(ws, tray, float(rng.uniform(0.03, 0.05)))
    return tray


def _task(name: str, role: str, description: str, **parts: Any) -> dict[str, Any]:
    return {
        "task": name,
        "role": role,
        "kind": "tight-pack",
        "description": description,
        "workspace": "workspace.yaml",
        **parts,
    }


def tight_pack_files(ws: str, bodies: list[Body], redrawn: list[Body]) -> dict[str, dict[str, Any]]:
    """The target and its two predecessors: redrawn boxes of the same kind into the same tray,
    the first `PRE_FIRST` of them, then the rest."""
    names = [f"body{i}" for i in range(1, len(bodies) + 1)]

    def entries(drawn: list[Body], chosen: list[str]) -> dict[str, Any]:
        return {
            name: body_entry(drawn[names.index(name)], f"pose_src{name[4:]}", names.index(name))
            for name in chosen
        }

    def pack(
        name: str, role: str, description: str, drawn: list[Body], chosen: list[str], **extra: Any
    ) -> dict[str, Any]:
        return _task(
            f"{ws}-{name}",
            role,
            description,
            **extra,
            obstacles=["tray"],
            bodies=entries(drawn, chosen),
            skeleton=pack_layers(chosen, "region_tray"),
            goal=[f"On({b}, region_tray)" for b in chosen],
        )

    def predecessor(k: int, chosen: list[str]) -> dict[str, Any]:
        description = f"Predecessor of tight_pack: {len(chosen)} other boxes into the tray."
        return pack(f"tight_pack_pre{k}", "predecessor", description, redrawn, chosen)

    first, rest = names[:PRE_FIRST], names[PRE_FIRST:]
    return {
        "tight_pack.yaml": pack(
            "tight_pack",
            "target",
            f"Pack the {len(names)} boxes (shortest first) into the tray with top grasps; they "
            "cover half its floor, so each must leave room for the ones still to come.",
            bodies,
            names,
            predecessors=["tight_pack_pre1.yaml", "tight_pack_pre2.yaml"],
        ),
        "tight_pack_pre1.yaml": predecessor(1, first),
        "tight_pack_pre2.yaml": predecessor(2, rest),
    }


def _yaw(orientation: tuple[float, float, float, float]) -> float:
    x, y, z, w = orientation
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _aligned(yaw: float, axis: float) -> bool:
    """Whether a box at `yaw` has its x axis along `axis` (either way)."""
    turn = (yaw - axis) % math.pi
    return min(turn, math.pi - turn) <= ALIGNED


def witness(task_path: Path, slots: Mapping[str, tuple[float, float]]) -> dict[str, Any] | None:
    """Play the packing in the simulator, box by box in the skeleton's order: each box's
    placement seed puts it at its slot, and of the yaw seeds the first that passes the
    transition with the box along the tray's axes is kept. The whole binding, or None where a
    box has no such yaw."""
    from planner.sim import load_world

    world = load_world(task_path, seed=0)
    try:
        scene = world.scene
        state: object = world.initial_state()
        bindings: dict[str, Any] = {}
        for index, decision in enumerate(world.skeleton.decisions):
            body, region_name = world.pose_sources[decision.var]
            region = scene.region(region_name)
            half_x, half_y = scene.placement_extents(body, region_name)
            lx, ly = slots[body]
            if half_x <= 0 or half_y <= 0 or abs(lx) > half_x or abs(ly) > half_y:
                return None
            seed_xy = [round((lx / half_x + 1) / 2, 6), round((ly / half_y + 1) / 2, 6)]
            for k in range(YAW_SEEDS):
                value = [*seed_xy, k / YAW_SEEDS]
                outcome = world.transition(index, {**bindings, decision.var: value}, state)
                if not outcome.ok:
                    continue
                poses = dict(outcome.state.poses)  # type: ignore[attr-defined]
                if _aligned(_yaw(poses[body][1]), region.yaw):
                    bindings[decision.var] = value
                    state = outcome.state
                    break
            else:
                return None
        return bindings
    finally:
        world.close()

"""`cpkb tasks` (the tasks it knows) and `cpkb render` (a picture of a task, or of a binding)."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from cpkb.cli import CliError

if TYPE_CHECKING:
    from planner.sim import PyBulletWorld
    from planner.sim.render import Camera
    from planner.world import TransitionOutcome


def register(subparsers: argparse._SubParsersAction) -> None:
    tasks = subparsers.add_parser(
        "tasks",
        help="list the shipped tasks, one line each",
        description="The tasks shipped with cpkb: name, decision variables, and what the task "
        "asks; pass a name to `cpkb plan --task` or `cpkb render --task`.",
    )
    tasks.set_defaults(handler=run_tasks)
    render = subparsers.add_parser(
        "render",
        help="write a PNG of a task's scene (headless), or replay a binding",
        description="Draw a task's scene as a PNG without a display, or watch it in PyBullet's "
        "window. With --binding the decisions are executed first (each transition reports ok or "
        "why it failed) and the arm then returns to its home pose, so the picture shows where "
        "the bodies ended up.",
        epilog="Examples: cpkb render --task desk --out desk.png; "
        'cpkb render --task desk --out found.png --binding "$(cpkb plan --task desk --json '
        '--quiet | tail -1)" --camera=-120,-30,1.6 (a negative first number needs the =).',
    )
    render.add_argument("--task", required=True, help="a shipped task name or a task .yaml file")
    render.add_argument("--out", type=Path, help="the PNG to write")
    render.add_argument(
        "--binding",
        help='a binding as JSON, e.g. \'{"#dir1": "front", "#pose12": [0.5, 0.5, 0.5]}\' '
        "(or a `cpkb plan --json` line, whose `bindings` are used): executed before the picture",
    )
    render.add_argument(
        "--camera",
        type=_camera,
        metavar="YAW,PITCH,DISTANCE[,X,Y,Z]",
        help="where the picture is taken from: yaw and pitch in degrees (pitch < 0 looks down), "
        "distance in metres from the target point X,Y,Z (default target 0.5,0,0.1: the table); "
        "write --camera=-120,-30,1.6 when YAW is negative; default: behind and above the robot",
    )
    render.add_argument("--gui", action="store_true", help="open PyBullet's window and replay")
    render.add_argument("--seed", type=int, default=0, help="the run's seed (IK and planner)")
    render.set_defaults(handler=run_render)


def run_tasks(args: argparse.Namespace) -> int:
    from planner.tasks import TaskError, list_tasks

    try:
        tasks = list_tasks()
    except TaskError as exc:
        raise CliError(str(exc)) from None
    width = max(len(t.name) for t in tasks)
    for task in tasks:
        decisions = ", ".join(
            c.outputs[0] for layer in task.layers if layer.kind == "decision" for c in layer.calls
        )
        summary = task.description.split(". ")[0].rstrip(".")
        print(f"{task.name:<{width}}  <{decisions}>  {summary}")
    return 0


def _bindings(text: str | None) -> dict:
    if text is None:
        return {}
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CliError(f"--binding is not valid JSON ({exc.msg} at column {exc.colno})") from None
    if isinstance(data, dict) and isinstance(data.get("bindings"), dict):
        data = data["bindings"]
    if not isinstance(data, dict):
        raise CliError('--binding must be a JSON object such as {"#dir1": "front"}')
    return data


DEFAULT_TARGET = (0.5, 0.0, 0.1)


def _camera(text: str) -> Camera:
    """`YAW,PITCH,DISTANCE[,X,Y,Z]` as a render Camera."""
    from planner.sim.render import Camera

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not numbers separated by commas") from None
    if len(values) not in (3, 6):
        raise argparse.ArgumentTypeError(
            f"give YAW,PITCH,DISTANCE or YAW,PITCH,DISTANCE,X,Y,Z, not {len(values)} numbers"
        )
    if values[2] <= 0:
        raise argparse.ArgumentTypeError("the distance must be above 0 metres")
    target = tuple(values[3:]) if len(values) == 6 else DEFAULT_TARGET
    return Camera(values[0], values[1], values[2], (target[0], target[1], target[2]))


def _park_arm(world: PyBulletWorld, outcomes: Sequence[TransitionOutcome]) -> None:
    """Send the arm home once the binding is executed: left at its last place pose it stands in
    front of what it placed. A body still held (a binding that ends on a pick) goes with it."""
    from planner.sim.grasps import carried_pose
    from planner.sim.world import SimState

    last = outcomes[-1].state if outcomes and outcomes[-1].ok else None
    held = last.held if isinstance(last, SimState) else None
    scene = world.scene
    scene.set_arm(scene.task.workspace.robot.home)
    if held is not None:
        scene.set_pose(held.body, carried_pose(scene, held))


def run_render(args: argparse.Namespace) -> int:
    from planner.sim import load_world
    from planner.sim.render import mark_regions, replay, snapshot
    from planner.sim.scene import GuiUnavailable
    from planner.tasks import TaskError, load_task

    if args.out is None and not args.gui:
        raise CliError("give --out FILE.png, or --gui to watch")
    if args.out is not None and args.out.suffix.lower() != ".png":
        raise CliError(f"--out must name a .png file, got {args.out}")
    bindings = _bindings(args.binding)
    try:
        for warning in load_task(args.task).warnings:
            print(f"warning: {warning}", file=sys.stderr)
        world = load_world(args.task, seed=args.seed, gui=args.gui)
    except TaskError as exc:
        raise CliError(str(exc)) from None
    except GuiUnavailable as exc:
        raise CliError(f"{exc}; use --out FILE.png for a picture without one") from None
    try:
        known = {d.var for d in world.skeleton.decisions}
        unknown = sorted(set(bindings) - known)
        if unknown:
            raise CliError(
                f"--binding names {unknown[0]}, not a decision of {world.name} ({sorted(known)})"
            )
        try:
            outcomes = replay(world, bindings, delay=0.01 if args.gui else 0.0)
        except (KeyError, ValueError) as exc:
            raise CliError(str(exc).strip("'\"")) from None
        for index, outcome in enumerate(outcomes):
            verdict = "ok" if outcome.ok else f"FAILED: {outcome.failed.reason}"  # type: ignore[union-attr]
            print(f"transition {index}: {verdict}")
        if outcomes:
            _park_arm(world, outcomes)
        mark_regions(world)
        if args.out is not None:
            snapshot(world, args.out, camera=args.camera)
            print(f"wrote {args.out}")
        if args.gui:
            print("close the window or press Ctrl-C to quit", file=sys.stderr)
            import pybullet as p

            if args.camera is not None:
                camera = args.camera
                p.resetDebugVisualizerCamera(
                    camera.distance,
                    camera.yaw,
                    camera.pitch,
                    list(camera.target),
                    physicsClientId=world.client,
                )
            while p.isConnected(world.client):
                p.getKeyboardEvents(physicsClientId=world.client)
    finally:
        world.close()
    return 0

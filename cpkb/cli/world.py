"""`cpkb tasks` (the tasks it knows) and `cpkb render` (a picture of a task, or of a binding)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cpkb.cli import CliError


def register(subparsers: argparse._SubParsersAction) -> None:
    tasks = subparsers.add_parser("tasks", help="list the shipped tasks, one line each")
    tasks.set_defaults(handler=run_tasks)
    render = subparsers.add_parser(
        "render", help="write a PNG of a task's scene (headless), or replay a binding"
    )
    render.add_argument("--task", required=True, help="a shipped task name or a task .yaml file")
    render.add_argument("--out", type=Path, help="the PNG to write")
    render.add_argument(
        "--binding",
        help='a binding as JSON, e.g. \'{"#dir1": "front", "#pose12": [0.5, 0.5, 0.5]}\' '
        "(or a `cpkb plan --json` line, whose `bindings` are used): executed before the picture",
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
        mark_regions(world)
        if args.out is not None:
            snapshot(world, args.out)
            print(f"wrote {args.out}")
        if args.gui:
            print("close the window or press Ctrl-C to quit", file=sys.stderr)
            import pybullet as p

            while p.isConnected(world.client):
                p.getKeyboardEvents(physicsClientId=world.client)
    finally:
        world.close()
    return 0

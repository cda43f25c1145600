"""Read task and workspace YAML files into validated `Task` objects.

Every mistake raises `TaskError` naming the file and the field (`skeleton[3].transition[0]`),
so that a user writing their own task never sees a traceback.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from planner.tasks.checks import geometry_warnings, impossibility, start_conflict
from planner.tasks.reach import arm_joint_names, arm_reach
from planner.tasks.schema import (
    STACKING,
    BoxPart,
    Call,
    FixedBody,
    Goal,
    LayerSpec,
    MovableBody,
    NamedPose,
    PlannerSettings,
    Region,
    RobotSpec,
    Task,
    TaskError,
    Workspace,
    smaller,
)

GRASP_DIRECTIONS = ("front", "right", "top", "back", "left")
HOME_CONFIG = "config0"
# A workspace that names no tool link or gripper opening has the Panda's (panda.urdf's link
# between the fingertips; the Franka hand opens 0.08 m).
PANDA_URDF = "franka_panda/panda.urdf"  # the default arm (see `WorldGeometry.arm`)
PANDA_TOOL_LINK = "panda_grasptarget"
PANDA_GRIPPER_OPENING = 0.08
# operator -> (argument kinds, output kinds); kinds name what an argument must refer to.
OPERATORS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "Sample-grasp": (("body",), ("#dir",)),
    "Sample-pose": (("body", "region"), ("#pose",)),
    "Inv-kin": (("body", "pose", "grasp"), ("config",)),
    "Plan-motion": (("config", "config"), ("traj",)),
    "Move-Pick": (("body", "traj"), ()),
    "Move-Place": (("body", "traj"), ()),
}
DECISION_OPERATORS = ("Sample-grasp", "Sample-pose")
ROLES = ("target", "predecessor")
_CALL = re.compile(r"^\s*([A-Za-z][\w-]*)\s*\(([^()]*)\)\s*(?:->\s*(.*?))?\s*$")
_GOAL = re.compile(r"^\s*(On)\s*\(\s*([\w-]+)\s*,\s*([\w-]+)\s*\)\s*$")
_NAME = re.compile(r"^[A-Za-z][\w-]*$")
_DEFAULT_COLOR = (0.6, 0.6, 0.6, 1.0)


def data_dir() -> Path:
    return Path(str(resources.files("planner.tasks") / "data"))


class _Reader:
    """Field access with errors that carry the file name and the field path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, message: str) -> TaskError:
        return TaskError(f"{self.source}: {where}: {message}")

    def mapping(self, value: Any, where: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(where, f"expected a mapping, got {type(value).__name__}")
        return value

    def get(self, data: Mapping[str, Any], key: str, where: str, default: Any = ..., /) -> Any:
        if key in data:
            return data[key]
        if default is ...:
            raise self.fail(f"{where}.{key}" if where else key, "missing required field")
        return default

    def only(self, data: Mapping[str, Any], allowed: set[str], where: str) -> None:
        extra = sorted(set(data) - allowed)
        if extra:
            field = f"{where}.{extra[0]}" if where else str(extra[0])
            raise self.fail(field, f"unknown field (allowed: {', '.join(sorted(allowed))})")

    def number(self, value: Any, where: str, *, positive: bool = False) -> float:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise self.fail(where, f"expected a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(where, f"must be positive, got {value!r}")
        return float(value)

    def vector(self, value: Any, n: int, where: str, *, positive: bool = False) -> tuple:
        if not isinstance(value, list | tuple) or len(value) != n:
            raise self.fail(where, f"expected a list of {n} numbers, got {value!r}")
        return tuple(
            self.number(v, f"{where}[{i}]", positive=positive) for i, v in enumerate(value)
        )

    def name(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not _NAME.match(value):
            raise self.fail(where, f"expected a name (letters, digits, - or _), got {value!r}")
        return value

    def color(self, value: Any, where: str) -> tuple[float, float, float, float]:
        rgba = self.vector(value, 4, where)
        if not all(0.0 <= c <= 1.0 for c in rgba):
            raise self.fail(where, "colour components must be within [0, 1]")
        return rgba


def _read_yaml(path: Path) -> Any:
    try:
        text = path.read_text()
    except OSError as exc:
        raise TaskError(f"{path}: cannot read the file ({exc.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else "YAML"
        raise TaskError(
            f"{path}: {where}: not valid YAML ({getattr(exc, 'problem', exc)})"
        ) from None


def _fixed_body(r: _Reader, name: str, raw: Any, where: str) -> FixedBody:
    data = r.mapping(raw, where)
    r.only(data, {"position", "yaw", "size", "parts", "color"}, where)
    if ("size" in data) == ("parts" in data):
        raise r.fail(where, "give either `size` (one box) or `parts` (a list of boxes)")
    if "size" in data:
        parts: tuple[BoxPart, ...] = (
            BoxPart(r.vector(data["size"], 3, f"{where}.size", positive=True)),
        )
    else:
        raw_parts = data["parts"]
        if not isinstance(raw_parts, list) or not raw_parts:
            raise r.fail(f"{where}.parts", "expected a non-empty list of boxes")
        built = []
        for i, part in enumerate(raw_parts):
            pw = f"{where}.parts[{i}]"
            pd = r.mapping(part, pw)
            r.only(pd, {"size", "offset"}, pw)
            size = r.vector(r.get(pd, "size", pw), 3, f"{pw}.size", positive=True)
            offset = r.vector(pd.get("offset", [0, 0, 0]), 3, f"{pw}.offset")
            built.append(BoxPart(size, offset))
        parts = tuple(built)
    return FixedBody(
        name=name,
        position=r.vector(r.get(data, "position", where), 3, f"{where}.position"),
        yaw=math.radians(r.number(data.get("yaw", 0.0), f"{where}.yaw")),
        parts=parts,
        color=r.color(data.get("color", list(_DEFAULT_COLOR)), f"{where}.color"),
    )


def _named_bodies(r: _Reader, raw: Any, where: str) -> dict[str, FixedBody]:
    data = r.mapping(raw if raw is not None else {}, where)
    return {
        r.name(k, f"{where}.{k}"): _fixed_body(r, k, v, f"{where}.{k}") for k, v in data.items()
    }


def load_workspace(path: Path) -> Workspace:
    r = _Reader(str(path))
    data = r.mapping(_read_yaml(path), "top level")
    r.only(data, {"workspace", "robot", "fixed", "obstacles", "regions", "poses"}, "")
    robot_raw = r.mapping(r.get(data, "robot", ""), "robot")
    allowed = {"urdf", "base", "home", "tool_link", "tool_offset", "gripper_opening"}
    r.only(robot_raw, allowed, "robot")
    home = r.get(robot_raw, "home", "robot")
    if not isinstance(home, list) or not home:
        raise r.fail("robot.home", "expected the arm's joint angles (radians)")
    robot = RobotSpec(
        urdf=str(r.get(robot_raw, "urdf", "robot")),
        base=r.vector(robot_raw.get("base", [0, 0, 0]), 3, "robot.base"),
        home=r.vector(home, len(home), "robot.home"),
        tool_offset=r.vector(robot_raw.get("tool_offset", [0, 0, 0]), 3, "robot.tool_offset"),
        tool_link=r.name(robot_raw.get("tool_link", PANDA_TOOL_LINK), "robot.tool_link"),
        gripper_opening=r.number(
            robot_raw.get("gripper_opening", PANDA_GRIPPER_OPENING),
            "robot.gripper_opening",
            positive=True,
        ),
    )
    try:
        arm_reach(robot)
        joints = arm_joint_names(robot)
    except TaskError as exc:
        raise r.fail("robot", str(exc)) from None
    if len(joints) != len(robot.home):
        raise r.fail(
            "robot.home",
            f"expected {len(joints)} joint angles ({', '.join(joints)}), got {len(robot.home)}",
        )
    fixed = _named_bodies(r, r.get(data, "fixed", ""), "fixed")
    obstacles = _named_bodies(r, data.get("obstacles"), "obstacles")
    clash = sorted(set(fixed) & set(obstacles))
    if clash:
        raise r.fail(f"obstacles.{clash[0]}", "name already used by a fixed body")
    regions: dict[str, Region] = {}
    for key, raw in r.mapping(r.get(data, "regions", ""), "regions").items():
        where = f"regions.{key}"
        rd = r.mapping(raw, where)
        r.only(rd, {"center", "size", "yaw"}, where)
        regions[r.name(key, where)] = Region(
            name=key,
            center=r.vector(r.get(rd, "center", where), 3, f"{where}.center"),
            size=r.vector(r.get(rd, "size", where), 2, f"{where}.size", positive=True),
            yaw=math.radians(r.number(rd.get("yaw", 0.0), f"{where}.yaw")),
        )
    poses: dict[str, NamedPose] = {}
    for key, raw in r.mapping(data.get("poses") or {}, "poses").items():
        where = f"poses.{key}"
        pd = r.mapping(raw, where)
        r.only(pd, {"region", "xy", "yaw"}, where)
        region = r.name(r.get(pd, "region", where), f"{where}.region")
        if region not in regions:
            raise r.fail(f"{where}.region", f"unknown region {region!r}")
        poses[r.name(key, where)] = NamedPose(
            name=key,
            region=region,
            xy=r.vector(r.get(pd, "xy", where), 2, f"{where}.xy"),
            yaw=math.radians(r.number(pd.get("yaw", 0.0), f"{where}.yaw")),
        )
    name = r.name(data.get("workspace", path.stem), "workspace")
    return Workspace(name, robot, fixed, obstacles, regions, poses)


def parse_call(r: _Reader, raw: Any, where: str) -> Call:
    if not isinstance(raw, str):
        raise r.fail(
            where,
            f"expected an operator call such as 'Inv-kin(body, pose0, #dir1) -> #config1', "
            f"got {raw!r}",
        )
    m = _CALL.match(raw)
    if m is None:
        raise r.fail(
            where, f"cannot read operator call {raw!r}; write it as 'Name(arg, ...) -> #out'"
        )
    name, args_text, out_text = m.group(1), m.group(2), m.group(3)
    if name not in OPERATORS:
        raise r.fail(where, f"unknown operator {name!r} (known: {', '.join(OPERATORS)})")
    args = tuple(a.strip() for a in args_text.split(",")) if args_text.strip() else ()
    outputs = tuple(o.strip() for o in out_text.split(",")) if out_text else ()
    kinds, out_kinds = OPERATORS[name]
    if len(args) != len(kinds):
        raise r.fail(
            where, f"{name} takes {len(kinds)} arguments ({', '.join(kinds)}), got {len(args)}"
        )
    if len(outputs) != len(out_kinds):
        hint = (
            " (quote the line: in YAML ' #' starts a comment)"
            if "->" in raw and not outputs
            else ""
        )
        raise r.fail(where, f"{name} gives {len(out_kinds)} output(s), got {len(outputs)}{hint}")
    for o in outputs:
        if not o.startswith("#") or not _NAME.match(o[1:]):
            raise r.fail(where, f"output {o!r} must be a variable such as '#config1'")
    return Call(name, args, outputs)


def _check_arguments(
    r: _Reader, call: Call, where: str, produced: dict[str, str], task_names: dict[str, set[str]]
) -> None:
    kinds, out_kinds = OPERATORS[call.name]
    for arg, kind in zip(call.args, kinds, strict=True):
        if arg.startswith("#"):
            have = produced.get(arg)
            if have is None:
                raise r.fail(where, f"{arg} is used before any call produces it")
            want = {"pose": "#pose", "grasp": "#dir"}.get(kind, kind)
            if have != want:
                raise r.fail(
                    where, f"{arg} is a {have} output, but {call.name} needs a {kind} here"
                )
        elif arg not in task_names[kind] and not (
            kind in ("region", "pose") and arg in task_names["body"]
        ):
            known = ", ".join(sorted(task_names[kind])) or "none"
            raise r.fail(where, f"{arg!r} is not a {kind} of this task (known: {known})")
    if call.name == "Sample-pose" and call.args[0] == call.args[1]:
        raise r.fail(where, f"{call.args[0]} cannot stand on itself")
    for out, kind in zip(call.outputs, out_kinds, strict=True):
        if out in produced:
            raise r.fail(where, f"{out} is produced twice")
        produced[out] = kind


def _layers(r: _Reader, raw: Any, names: dict[str, set[str]]) -> tuple[LayerSpec, ...]:
    if not isinstance(raw, list) or not raw:
        raise r.fail("skeleton", "expected a non-empty list of layers")
    produced: dict[str, str] = {}
    layers: list[LayerSpec] = []
    for i, layer in enumerate(raw):
        where = f"skeleton[{i}]"
        ld = r.mapping(layer, where)
        if len(ld) != 1 or next(iter(ld)) not in ("decision", "transition"):
            raise r.fail(
                where, "each layer is either `decision: <call>` or `transition: [<call>, ...]`"
            )
        kind, body = next(iter(ld.items()))
        expected = "decision" if i % 2 == 0 else "transition"
        if kind != expected:
            raise r.fail(where, f"layers alternate decision, transition, ...: expected {expected}")
        raw_calls = [body] if kind == "decision" else body
        if not isinstance(raw_calls, list) or not raw_calls:
            raise r.fail(f"{where}.{kind}", "expected a non-empty list of operator calls")
        calls = []
        for j, raw_call in enumerate(raw_calls):
            cw = f"{where}.{kind}" + ("" if kind == "decision" else f"[{j}]")
            call = parse_call(r, raw_call, cw)
            if (call.name in DECISION_OPERATORS) != (kind == "decision"):
                raise r.fail(cw, f"{call.name} does not belong in a {kind} layer")
            _check_arguments(r, call, cw, produced, names)
            calls.append(call)
        layers.append(LayerSpec(kind, tuple(calls)))
    if layers[-1].kind != "transition":
        raise r.fail("skeleton", "the last layer must be a transition layer")
    return tuple(layers)


def _resolve_workspace(r: _Reader, value: Any, task_path: Path) -> Path:
    if not isinstance(value, str) or not value:
        raise r.fail("workspace", "expected a workspace name or a path to a workspace file")
    if value.endswith((".yaml", ".yml")):
        path = (task_path.parent / value).resolve()
    else:
        path = data_dir() / "workspaces" / f"{value}.yaml"
    if not path.is_file():
        raise r.fail("workspace", f"no workspace file {value!r} (looked for {path})")
    return path


def is_task_file_reference(text: str) -> bool:
    """A path (`../other/task.yaml`, `dir/task`) rather than a shipped task's name."""
    return "/" in text or text.endswith((".yaml", ".yml"))


def shipped_names() -> list[str]:
    return sorted(p.stem for p in data_dir().glob("*.yaml"))


def _predecessors(r: _Reader, raw: Any, path: Path, visiting: tuple[Path, ...]) -> tuple[str, ...]:
    """The declared predecessors, each loaded (so a broken one is reported here) and checked
    not to lead back to this task: shipped names as given, files as resolved paths."""
    if raw is None:
        return ()
    if not isinstance(raw, list) or not all(isinstance(x, str) and x for x in raw):
        raise r.fail("predecessors", "expected a list of shipped task names or task file paths")
    chain = (*visiting, path.resolve())
    resolved: list[str] = []
    for i, ref in enumerate(raw):
        where = f"predecessors[{i}]"
        if is_task_file_reference(ref):
            target = (path.parent / ref).resolve()
            if not target.is_file():
                raise r.fail(where, f"no task file {ref!r} (looked for {target})")
            name = str(target)
        else:
            target = (data_dir() / f"{ref}.yaml").resolve()
            if not target.is_file():
                known = ", ".join(shipped_names())
                raise r.fail(where, f"no shipped task {ref!r} (shipped: {known}; or a .yaml path)")
            name = ref
        if target in chain:
            loop = (*chain[chain.index(target) :], target)
            raise r.fail(where, f"predecessors form a cycle: {' -> '.join(p.name for p in loop)}")
        if name in resolved:
            raise r.fail(where, f"{ref!r} is named twice")
        try:
            load_task_file(target, _visiting=chain)
        except TaskError as exc:
            raise r.fail(where, str(exc)) from None
        resolved.append(name)
    return tuple(resolved)


def load_task_file(path: Path, *, _visiting: tuple[Path, ...] = ()) -> Task:
    r = _Reader(str(path))
    data = r.mapping(_read_yaml(path), "top level")
    allowed = {
        "task",
        "description",
        "workspace",
        "obstacles",
        "bodies",
        "skeleton",
        "goal",
        "settings",
        "predecessors",
        "role",
        "kind",
        "stacking",
    }
    r.only(data, allowed, "")
    stacking = data.get("stacking", "free")
    if stacking not in STACKING:
        raise r.fail("stacking", f"expected one of {', '.join(STACKING)}, got {stacking!r}")
    role = data.get("role")
    if role not in (None, *ROLES):
        raise r.fail("role", f"expected one of {', '.join(ROLES)}, got {role!r}")
    kind = r.name(data["kind"], "kind") if "kind" in data else None
    try:
        workspace = load_workspace(_resolve_workspace(r, r.get(data, "workspace", ""), path))
    except TaskError as exc:
        raise r.fail("workspace", str(exc)) from None
    obstacles = data.get("obstacles") or []
    if not isinstance(obstacles, list):
        raise r.fail("obstacles", "expected a list of obstacle names")
    for i, ob in enumerate(obstacles):
        if ob not in workspace.obstacles:
            known = ", ".join(workspace.obstacles)
            raise r.fail(
                f"obstacles[{i}]",
                f"workspace {workspace.name} has no obstacle {ob!r} (known: {known})",
            )
    bodies: dict[str, MovableBody] = {}
    for key, raw in r.mapping(r.get(data, "bodies", ""), "bodies").items():
        where = f"bodies.{key}"
        r.name(key, where)
        if key in workspace.fixed or key in workspace.obstacles:
            raise r.fail(where, "name already used by a body of the workspace")
        bd = r.mapping(raw, where)
        r.only(bd, {"size", "pose", "color"}, where)
        pose = r.get(bd, "pose", where)
        if not isinstance(pose, str) or (
            pose not in workspace.poses and pose not in data["bodies"]
        ):
            raise r.fail(
                f"{where}.pose",
                f"unknown pose {pose!r} (known: {', '.join(workspace.poses)}; or a movable "
                "body's name, to start on its top)",
            )
        bodies[key] = MovableBody(
            name=key,
            size=r.vector(r.get(bd, "size", where), 3, f"{where}.size", positive=True),
            pose=pose,
            color=r.color(bd.get("color", [0.9, 0.5, 0.1, 1.0]), f"{where}.color"),
        )
    if not bodies:
        raise r.fail("bodies", "a task needs at least one movable body")
    conflict = start_conflict(workspace, bodies, stacking)
    if conflict is not None:
        raise r.fail(conflict.where, conflict.message)
    names = {
        "body": set(bodies),
        "region": set(workspace.regions),
        "pose": set(workspace.poses),
        "grasp": set(GRASP_DIRECTIONS),
        "config": {HOME_CONFIG},
        "traj": set(),
    }
    # A task without a skeleton is posed by its goal alone (`planner.goals` finds skeletons).
    layers = _layers(r, data["skeleton"], names) if "skeleton" in data else ()
    goals = []
    raw_goal = r.get(data, "goal", "")
    if not isinstance(raw_goal, list) or not raw_goal:
        raise r.fail("goal", "expected a list such as ['On(body, region2)']")
    for i, g in enumerate(raw_goal):
        m = _GOAL.match(g) if isinstance(g, str) else None
        if m is None:
            raise r.fail(
                f"goal[{i}]", f"expected 'On(body, region)' or 'On(body, other_body)', got {g!r}"
            )
        supports = set(workspace.regions) | (set(bodies) - {m.group(2)})
        if m.group(2) not in bodies or m.group(3) not in supports:
            raise r.fail(f"goal[{i}]", f"{g!r} names an unknown body or region")
        if (
            stacking == "towers"
            and m.group(3) in bodies
            and not smaller(bodies[m.group(2)], bodies[m.group(3)])
        ):
            raise r.fail(
                f"goal[{i}]",
                f"{g!r}: {m.group(3)} is not larger than {m.group(2)}, and with stacking: towers "
                "a body stands only on a larger one",
            )
        placements = {c.args for layer in layers for c in layer.calls if c.name == "Sample-pose"}
        if layers and (m.group(2), m.group(3)) not in placements:
            raise r.fail(
                f"goal[{i}]",
                f"no Sample-pose({m.group(2)}, {m.group(3)}) in the skeleton puts "
                f"{m.group(2)} in {m.group(3)}",
            )
        goals.append(Goal(m.group(1), m.group(2), m.group(3)))
    impossible = impossibility(workspace, bodies, layers, tuple(goals))
    if impossible is not None:
        raise r.fail(impossible.where, impossible.message)
    settings_raw = r.mapping(data.get("settings") or {}, "settings")
    defaults = PlannerSettings()
    r.only(settings_raw, set(defaults.__dataclass_fields__), "settings")
    values: dict[str, Any] = {
        k: (int if isinstance(getattr(defaults, k), int) else float)(
            r.number(v, f"settings.{k}", positive=True)
        )
        for k, v in settings_raw.items()
    }
    settings = PlannerSettings(**values)
    predecessors = _predecessors(r, data.get("predecessors"), path, _visiting)
    return Task(
        name=r.name(data.get("task", path.stem), "task"),
        description=str(data.get("description", "")).strip(),
        source=str(path),
        workspace=workspace,
        obstacles=tuple(obstacles),
        bodies=bodies,
        layers=layers,
        goal=tuple(goals),
        settings=settings,
        predecessors=predecessors,
        role=role,
        kind=kind,
        warnings=geometry_warnings(workspace, bodies, layers),
        stacking=stacking,
    )

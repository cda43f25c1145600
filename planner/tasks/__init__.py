"""Tasks as data: the shipped task files, the loader, and the skeleton a task gives the search.

`load_task("desk")` reads a shipped task; `load_task("my.yaml")` reads a user's file. Both
raise `TaskError` naming the file and the field on any mistake.
"""

from __future__ import annotations

from pathlib import Path

from contract.models import CategoricalDomain, ContinuousDomain
from planner.skeleton import DecisionVar, Layer, OperatorCall, Skeleton
from planner.tasks.loader import GRASP_DIRECTIONS, data_dir, load_task_file, load_workspace
from planner.tasks.schema import Task, TaskError

__all__ = [
    "GRASP_APPROACH",
    "GRASP_DIRECTIONS",
    "Task",
    "TaskError",
    "build_skeleton",
    "grasp_domain",
    "list_tasks",
    "load_task",
    "load_workspace",
    "pose_domain",
]

# Unit vector along which the gripper moves onto the body, in the robot-relative frame of the
# body (x: from the robot base toward the body, y: to the robot's left, z: up).
GRASP_APPROACH: dict[str, tuple[float, float, float]] = {
    "front": (1.0, 0.0, 0.0),
    "right": (0.0, 1.0, 0.0),
    "top": (0.0, 0.0, -1.0),
    "back": (-1.0, 0.0, 0.0),
    "left": (0.0, -1.0, 0.0),
}
SHIPPED_ORDER = ("deskP", "desk", "regrasp", "packP1", "packP2", "packP3", "pack")


def grasp_domain() -> CategoricalDomain:
    return CategoricalDomain(
        choices=list(GRASP_DIRECTIONS),
        embedding={d: list(GRASP_APPROACH[d]) for d in GRASP_DIRECTIONS},
    )


def pose_domain(region: str | None = None) -> ContinuousDomain:
    """A placement seed (x, y, yaw) in [0, 1]^3, mapped into `region` by the world (its frame:
    two seeds in one region are places side by side). The yaw seed is the placing hand's heading
    in the region's axes, `(2 yaw - 1) pi` (`Scene.region_pose`), hence `heading=2`."""
    return ContinuousDomain(
        low=[0.0, 0.0, 0.0],
        high=[1.0, 1.0, 1.0],
        frame=region,
        heading=2 if region is not None else None,
    )


def list_tasks() -> list[Task]:
    """The shipped tasks, predecessors before their targets."""
    files = {p.stem: p for p in (data_dir()).glob("*.yaml")}
    ordered = [n for n in SHIPPED_ORDER if n in files] + sorted(set(files) - set(SHIPPED_ORDER))
    return [load_task_file(files[n]) for n in ordered]


def load_task(task: str | Path) -> Task:
    """A shipped task by name, or a task file by path."""
    text = str(task)
    shipped = data_dir() / f"{text}.yaml"
    if "/" not in text and not text.endswith((".yaml", ".yml")):
        if not shipped.is_file():
            known = ", ".join(t for t in SHIPPED_ORDER)
            raise TaskError(f"{text}: no such task (shipped: {known}; or give a .yaml file)")
        return load_task_file(shipped)
    return load_task_file(Path(text))


def build_skeleton(task: Task) -> Skeleton:
    """The skeleton of the seam: operator calls with the paper's names, decision variables
    with task-independent kinds (`#dir`, `#pose`) and their domains."""
    layers = []
    for spec in task.layers:
        calls = tuple(OperatorCall(c.name, c.args, c.outputs) for c in spec.calls)
        decision = None
        if spec.kind == "decision":
            call = calls[0]
            grasp = call.name == "Sample-grasp"
            decision = DecisionVar(
                var=call.outputs[0],
                kind="#dir" if grasp else "#pose",
                domain=grasp_domain() if grasp else pose_domain(call.args[1]),
                producer=call,
            )
        layers.append(Layer(kind=spec.kind, calls=calls, decision=decision))  # type: ignore[arg-type]
    return Skeleton(layers=tuple(layers))

"""A symbolic plan's moves written out as cpkb's operator calls: the skeleton a task file
would give by hand (see `planner/tasks/README.md`), with the same kinds of decision."""

from __future__ import annotations

from dataclasses import replace

from planner.goals.pddl import Plan
from planner.tasks.loader import HOME_CONFIG
from planner.tasks.schema import Call, LayerSpec, Task


def plan_layers(task: Task, plan: Plan) -> tuple[LayerSpec, ...]:
    """Per move: grasp the body where it stands (its start pose, or the place it was put), then
    place it. Variables are numbered by move: `#dir1`, `#pose1`, `#config1g`, `#config1p`."""
    stands = {name: body.pose for name, body in task.bodies.items()}
    config = HOME_CONFIG
    layers: list[LayerSpec] = []
    for i, move in enumerate(plan.moves, start=1):
        body = move.body
        grasp, pose = f"#dir{i}", f"#pose{i}"
        at_grasp, at_place = f"#config{i}g", f"#config{i}p"
        layers.append(LayerSpec("decision", (Call("Sample-grasp", (body,), (grasp,)),)))
        layers.append(
            LayerSpec(
                "transition",
                (
                    Call("Inv-kin", (body, stands[body], grasp), (at_grasp,)),
                    Call("Plan-motion", (config, at_grasp), (f"#traj{i}g",)),
                    Call("Move-Pick", (body, f"#traj{i}g"), ()),
                ),
            )
        )
        layers.append(LayerSpec("decision", (Call("Sample-pose", (body, move.place), (pose,)),)))
        layers.append(
            LayerSpec(
                "transition",
                (
                    Call("Inv-kin", (body, pose, grasp), (at_place,)),
                    Call("Plan-motion", (at_grasp, at_place), (f"#traj{i}p",)),
                    Call("Move-Place", (body, f"#traj{i}p"), ()),
                ),
            )
        )
        stands[body], config = pose, at_place
    return tuple(layers)


def describe(plan: Plan) -> str:
    """`move blocker to region3, then goal to region2`."""
    return "move " + ", then ".join(f"{m.body} to {m.place}" for m in plan.moves)


def skeleton_task(task: Task, plan: Plan) -> Task:
    """The task with the plan's skeleton, as if written by hand."""
    return replace(task, layers=plan_layers(task, plan))

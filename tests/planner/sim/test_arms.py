"""Other arms: the robot's URDF, tool frame, gripper opening and home come from the workspace
file; the xArm6 workspace runs desk-, regrasp- and pack-like tasks; its failure graphs name the
arm, so knowledge learnt with one arm does not steer another."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner.failures.graphs import Encodings, failure_graph
from planner.run import run_plan
from planner.sim import load_world
from planner.tasks import load_task
from planner.tasks.schema import TaskError
from planner.world import CheckResult

XARM = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "xarm"


def test_the_xarm_comes_from_its_workspace_file() -> None:
    world = load_world(XARM / "desk.yaml", seed=0)
    try:
        scene = world.scene
        assert len(scene.arm_joints) == 6 and scene.finger_joints == ()
        assert scene.max_finger_opening == pytest.approx(0.0425)
        assert world.scene.arm() == pytest.approx(world.task.workspace.robot.home)
        # The tool centre point is 0.172 m beyond the flange, along the flange's axis.
        (x, y, z), _ = scene.tcp()
        assert 0.3 < x < 0.5 and abs(y) < 1e-6 and 0.1 < z < 0.4
        assert scene.contacts() == []  # the gripper's own linkage is not a collision
    finally:
        world.close()


def test_a_home_of_the_wrong_length_names_the_arm_joints(tmp_path: Path) -> None:
    text = (XARM / "workspace.yaml").read_text()
    (tmp_path / "workspace.yaml").write_text(
        text.replace("home: [0.0, -0.3, -1.0, 0.0, 1.3, 0.0]", "home: [0.0, -0.3, -1.0]")
    )
    (tmp_path / "desk.yaml").write_text((XARM / "desk.yaml").read_text())
    with pytest.raises(TaskError) as caught:
        load_task(str(tmp_path / "desk.yaml"))
    assert str(caught.value).endswith(
        "workspace.yaml: robot.home: expected 6 joint angles (joint1, joint2, joint3, joint4, "
        "joint5, joint6), got 3"
    )


@pytest.mark.parametrize(
    ("task", "seed"),
    [("desk", 0), ("regrasp", 1), pytest.param("pack", 1, marks=pytest.mark.slow)],
)
def test_the_xarm_solves_desk_regrasp_and_pack_like_tasks(task: str, seed: int) -> None:
    result = run_plan(str(XARM / f"{task}.yaml"), "quasi-random", seed, max_rollouts=400)
    assert result.solved, result.notes


def test_knowledge_is_about_one_arm() -> None:
    labels = {}
    for arm, task in (("xarm", XARM / "desk.yaml"), ("panda", "desk")):
        world = load_world(task, seed=0)
        try:
            call = world.skeleton.transitions[0].calls[0]
            graph = failure_graph(
                world.skeleton,
                0,
                CheckResult(call, False, "no IK"),
                encodings=Encodings(world.geometry),
            )
        finally:
            world.close()
        labels[arm] = {node.label for node in graph.graph.nodes}
    assert labels["xarm"] - labels["panda"] == {"arm:xarm/xarm6_with_gripper.urdf"}
    assert not any(label.startswith("arm:") for label in labels["panda"])

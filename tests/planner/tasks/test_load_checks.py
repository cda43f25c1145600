"""Load-time checks: a task no binding can solve is refused with what is wrong, before any
rollout, as one line naming the file and the field; `cpkb plan` exits 2 with it."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_support import cpkb_in_process

from planner.tasks import load_task
from planner.tasks.loader import data_dir
from planner.tasks.reach import arm_reach
from planner.tasks.schema import TaskError

TASK = """\
task: checked
workspace: {workspace}
bodies:
  body: {{size: {size}, pose: {pose}}}
skeleton:
  - decision: "Sample-grasp(body) -> #dir1"
  - transition:
      - "Inv-kin(body, {pose}, #dir1) -> #config1"
      - "Plan-motion(config0, #config1) -> #traj01"
      - "Move-Pick(body, #traj01)"
  - decision: "Sample-pose(body, {region}) -> #pose13"
  - transition:
      - "Inv-kin(body, #pose13, #dir1) -> #config3"
      - "Plan-motion(#config1, #config3) -> #traj13"
      - "Move-Place(body, #traj13)"
goal: ["On(body, {region})"]
"""
TABLETOP = (data_dir() / "workspaces" / "tabletop.yaml").read_text()


def write(
    tmp_path: Path,
    *,
    size: str = "[0.05, 0.05, 0.12]",
    pose: str = "pose0",
    region: str = "region3",
    workspace: str = "tabletop",
    replace: tuple[str, str] | None = None,
) -> Path:
    if replace is not None:
        changed = TABLETOP.replace(*replace)
        assert changed != TABLETOP
        (tmp_path / "ws.yaml").write_text(changed)
        workspace = "ws.yaml"
    path = tmp_path / "checked.yaml"
    path.write_text(TASK.format(size=size, pose=pose, region=region, workspace=workspace))
    return path


def refusal(path: Path) -> str:
    with pytest.raises(TaskError) as caught:
        load_task(str(path))
    return str(caught.value)


def test_a_task_that_can_work_loads(tmp_path: Path) -> None:
    assert load_task(str(write(tmp_path))).name == "checked"


def test_a_body_wider_than_the_gripper_opens_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, size="[0.07, 0.07, 0.12]")
    assert refusal(path) == (
        f"{path}: bodies.body.size: body is 0.070 x 0.070 m across, but the gripper opens "
        "0.080 m and holds at most 0.060 m (0.01 m clear of each finger): no grasp can pick it"
    )
    # One side narrow enough is a grasp: across that side.
    assert load_task(str(write(tmp_path, size="[0.05, 0.09, 0.12]"))).name == "checked"


def test_a_start_pose_out_of_reach_is_refused(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        replace=(
            "pose0: {region: region1, xy: [0.45, 0.3]",
            "pose0: {region: region1, xy: [1.3, 0.6]",
        ),
    )
    assert refusal(path) == (
        f"{path}: bodies.body.pose: body starts at pose0, 1.45 m from the arm's shoulder: beyond "
        "the 1.09 m franka_panda/panda.urdf reaches at most, no grasp can pick it"
    )


def test_a_goal_no_operator_can_reach_is_refused(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        replace=(
            "region3: {center: [0.36, 0.0, 0.0], size: [0.2, 0.2]}",
            "region3: {center: [1.4, 0.0, 0.0], size: [0.2, 0.2]}",
        ),
    )
    assert refusal(path) == (
        f"{path}: goal[0]: On(body, region3): every place in region3 is at least 1.35 m from the "
        "arm's shoulder, beyond the 1.09 m franka_panda/panda.urdf reaches at most: no operator "
        "can put body there"
    )


def test_a_region_no_body_fits_in_is_refused(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        replace=(
            "region3: {center: [0.36, 0.0, 0.0], size: [0.2, 0.2]}",
            "region3: {center: [0.36, 0.0, 0.0], size: [0.2, 0.04]}",
        ),
    )
    assert refusal(path) == (
        f"{path}: skeleton[2].decision: no place in region3 (0.200 x 0.040 m) fits body: its "
        "narrower side, 0.050 m, is wider than the region at any yaw"
    )


def test_the_reach_bound_holds_what_the_arm_reaches() -> None:
    """The Panda's bound lies beyond its stated 0.855 m (a sound bound, never too short)."""
    reach = arm_reach(load_task("desk").workspace.robot)
    assert reach.shoulder == pytest.approx((0.0, 0.0, 0.333))
    assert 0.855 < reach.bound < 1.2


def test_a_missing_tool_link_is_named(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        replace=("tool_link: panda_grasptarget", "tool_link: tcp"),
    )
    assert refusal(path).endswith("ws.yaml: robot: franka_panda/panda.urdf has no link 'tcp'")


def test_plan_refuses_an_impossible_task_in_one_line_before_any_rollout(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, size="[0.07, 0.07, 0.12]")
    out = cpkb_in_process(capfd, "plan", "--task", str(path), "--method", "quasi-random")
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [
        f"cpkb plan: error: {path}: bodies.body.size: body is 0.070 x 0.070 m across, but the "
        "gripper opens 0.080 m and holds at most 0.060 m (0.01 m clear of each finger): no "
        "grasp can pick it"
    ]


BLOCKED = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "external" / "blocked"


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "block: {size: [0.05, 0.05, 0.12]",
            "block: {size: [0.07, 0.07, 0.12]",
            "bodies.block.size: block is 0.070 x 0.070 m across, but the gripper opens 0.080 m "
            "and holds at most 0.060 m (0.01 m clear of each finger): no grasp can pick it",
        ),
        (
            'goal: ["On(block, goal)"]',
            'goal: ["On(block, stall)", "On(blocker, block)"]',
            "goal[1]: no place in block (0.050 x 0.050 m) fits blocker: its narrower side, "
            "0.060 m, is wider than the region at any yaw",
        ),
    ],
)
def test_a_goal_only_task_is_checked_for_the_bodies_its_goal_moves(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    text = (BLOCKED / "blocked.yaml").read_text()
    if "blocker, block" in new:
        text = text.replace(
            "blocker: {size: [0.05, 0.05, 0.12]", "blocker: {size: [0.06, 0.06, 0.12]"
        )
    assert old in text
    (tmp_path / "workspace.yaml").write_text((BLOCKED / "workspace.yaml").read_text())
    path = tmp_path / "blocked.yaml"
    path.write_text(text.replace(old, new))
    assert refusal(path) == f"{path}: {message}"

"""A body may start on another (a tower): the loader, the simulator and the PDDL problem agree
on it, and a start no scene can hold is refused when the task loads, with what is wrong."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from cli_support import cpkb_in_process

from planner.goals.pddl import problem, top_plans
from planner.goals.skeletons import skeleton_task
from planner.sim.world import PyBulletWorld
from planner.tasks import load_task
from planner.tasks.schema import TaskError

ROOT = Path(__file__).resolve().parents[3]
HANOI = ROOT / "benchmarks" / "suites" / "external" / "hanoi"

TOWER = """\
task: tower
workspace: {workspace}
{stacking}
bodies:
{bodies}
goal: ["On(top, peg3)"]
"""


def write(tmp_path: Path, bodies: str, stacking: str = "") -> Path:
    path = tmp_path / "tower.yaml"
    workspace = HANOI / "workspace.yaml"
    path.write_text(TOWER.format(workspace=workspace, stacking=stacking, bodies=bodies))
    return path


def test_a_tower_stands_in_the_scene_as_the_task_states_it() -> None:
    task = load_task(str(HANOI / "hanoi3.yaml"))
    assert task.bodies["d2"].pose == "d3" and task.bodies["d1"].pose == "d2"
    world = PyBulletWorld(skeleton_task(task, top_plans(task, 40)[0]), seed=0)
    try:
        scene = world.scene
        (x3, y3, z3), _ = scene.pose("d3")
        (x1, y1, z1), _ = scene.pose("d1")
        assert math.dist((x1, y1), (x3, y3)) < 1e-6 and math.dist((x1, y1), (0.5, 0.22)) < 1e-6
        h = {b: task.bodies[b].size[2] for b in ("d1", "d2", "d3")}
        heights = h["d3"] / 2 + h["d2"] + h["d1"] / 2
        assert z1 - z3 == pytest.approx(heights + 0.002, abs=1e-6)  # 1 mm above each support
        assert scene.in_region("d1", "d2") and scene.in_region("d2", "d3")
        assert scene.in_region("d3", "peg1")
        # A world's start is the task's, whatever a search sharing its scene left behind.
        scene.set_pose("d3", ((0.5, -0.22, 0.2), (0.0, 0.0, 0.0, 1.0)))
        assert dict(scene.start_poses())["d1"][0][:2] == pytest.approx((0.5, 0.22))
    finally:
        world.close()


def test_the_pddl_start_has_the_tower_with_only_its_top_clear() -> None:
    text = problem(load_task(str(HANOI / "hanoi3.yaml")))
    for fact in ("(on d3 peg1)", "(on-body d2 d3)", "(on-body d1 d2)", "(clear d1)"):
        assert fact in text
    assert "(clear d2)" not in text and "(clear d3)" not in text
    assert "(free peg2)" in text and "(free peg3)" in text and "(free peg1)" not in text


@pytest.mark.parametrize(
    ("bodies", "stacking", "field", "words"),
    [
        ("  top: {size: [0.04, 0.04, 0.04], pose: top}", "", "bodies.top.pose", "on itself"),
        (
            "  top: {size: [0.04, 0.04, 0.04], pose: low}\n"
            "  low: {size: [0.05, 0.05, 0.04], pose: top}",
            "",
            "bodies.top.pose",
            "top on low on top: the bodies stand on each other in a circle",
        ),
        (
            "  base: {size: [0.05, 0.05, 0.04], pose: on_peg1}\n"
            "  top: {size: [0.04, 0.04, 0.04], pose: base}\n"
            "  other: {size: [0.04, 0.04, 0.04], pose: base}",
            "",
            "bodies.other.pose",
            "top and other both start on base",
        ),
        (
            "  base: {size: [0.04, 0.04, 0.04], pose: on_peg1}\n"
            "  top: {size: [0.05, 0.05, 0.04], pose: base}",
            "stacking: towers",
            "bodies.top.pose",
            "top starts on base, which is not larger",
        ),
        (
            "  base: {size: [0.05, 0.05, 0.04], pose: on_peg1}\n"
            "  top: {size: [0.04, 0.04, 0.04], pose: on_peg1}",
            "",
            "bodies.top.pose",
            "top at on_peg1 overlaps base at on_peg1",
        ),
        (
            "  top: {size: [0.04, 0.04, 0.04], pose: nowhere}",
            "",
            "bodies.top.pose",
            "unknown pose 'nowhere'",
        ),
    ],
)
def test_an_inconsistent_start_is_refused_naming_the_body(
    tmp_path: Path, bodies: str, stacking: str, field: str, words: str
) -> None:
    path = write(tmp_path, bodies, stacking)
    with pytest.raises(TaskError) as err:
        load_task(str(path))
    assert str(err.value).startswith(f"{path}: {field}: ")
    assert words in str(err.value)


def test_plan_prints_an_inconsistent_start_as_one_line_and_exits_2(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    path = write(
        tmp_path,
        "  base: {size: [0.05, 0.05, 0.04], pose: on_peg1}\n"
        "  top: {size: [0.04, 0.04, 0.04], pose: base}\n"
        "  other: {size: [0.04, 0.04, 0.04], pose: base}",
    )
    out = cpkb_in_process(capfd, "plan", "--task", str(path), "--method", "quasi-random")
    assert out.returncode == 2
    lines = [line for line in out.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "top and other both start on base" in lines[0], out.stderr
    assert "Traceback" not in out.stderr

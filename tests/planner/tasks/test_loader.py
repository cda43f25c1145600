"""Shipped tasks load; a user's task file with a mistake gets an error naming file and field."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner.tasks import build_skeleton, list_tasks, load_task
from planner.tasks.schema import TaskError

SHIPPED = ["deskP", "desk", "regrasp", "packP1", "packP2", "packP3", "pack"]

GOOD = """\
task: mine
workspace: tabletop
obstacles: [obstacle1]
bodies:
  body: {size: [0.06, 0.06, 0.16], pose: pose0}
skeleton:
  - decision: "Sample-grasp(body) -> #dir1"
  - transition:
      - "Inv-kin(body, pose0, #dir1) -> #config1"
      - "Plan-motion(config0, #config1) -> #traj01"
      - "Move-Pick(body, #traj01)"
  - decision: "Sample-pose(body, region3) -> #pose13"
  - transition:
      - "Inv-kin(body, #pose13, #dir1) -> #config3"
      - "Plan-motion(#config1, #config3) -> #traj13"
      - "Move-Place(body, #traj13)"
goal: ["On(body, region3)"]
"""


def test_every_shipped_task_loads_with_its_skeleton() -> None:
    tasks = {t.name: t for t in list_tasks()}
    assert list(tasks) == SHIPPED
    kinds = {n: [d.kind for d in build_skeleton(t).decisions] for n, t in tasks.items()}
    assert kinds["desk"] == ["#dir", "#pose"]
    assert kinds["regrasp"] == ["#dir", "#pose", "#dir", "#pose"]
    assert kinds["pack"] == ["#pose", "#pose", "#pose"]
    desk = build_skeleton(tasks["desk"])
    assert desk.transitions[0].calls[0].args == ("body", "pose0", "#dir1")
    assert desk.decisions[0].domain.choices == ["front", "right", "top", "back", "left"]
    regrasp = build_skeleton(tasks["regrasp"]).decisions
    assert [d.domain.frame for d in regrasp if d.kind == "#pose"] == ["region3", "region2"]
    assert {d.domain.frame for d in build_skeleton(tasks["pack"]).decisions} == {"region5"}


def test_pack_target_region_has_a_quarter_less_area_than_the_source() -> None:
    regions = load_task("pack").workspace.regions
    area = {n: regions[n].size[0] * regions[n].size[1] for n in ("region4", "region5")}
    assert area["region5"] == pytest.approx(0.75 * area["region4"], rel=1e-3)


def test_a_user_file_loads_by_path(tmp_path: Path) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text(GOOD)
    task = load_task(str(path))
    assert task.name == "mine"
    assert task.obstacles == ("obstacle1",)


@pytest.mark.parametrize(
    ("old", "new", "field", "words"),
    [
        (
            '"Plan-motion(config0, #config1) -> #traj01"',
            '"Plan-moton(config0, #config1) -> #traj01"',
            "skeleton[1].transition[1]",
            "unknown operator",
        ),
        ("pose: pose0}", "pose: pose9}", "bodies.body.pose", "unknown pose"),
        (
            '"Sample-grasp(body) -> #dir1"',
            "Sample-grasp(body) -> #dir1",
            "skeleton[0].decision",
            "comment",
        ),
        ("obstacles: [obstacle1]", "obstacles: [obstacle7]", "obstacles[0]", "no obstacle"),
        (
            '"Inv-kin(body, #pose13, #dir1) -> #config3"',
            '"Inv-kin(body, #pose13, #dir9) -> #config3"',
            "skeleton[3].transition[0]",
            "#dir9 is used before",
        ),
        (
            "size: [0.06, 0.06, 0.16]",
            "size: [0.06, -0.06, 0.16]",
            "bodies.body.size[1]",
            "positive",
        ),
        ("workspace: tabletop", "workspace: nowhere", "workspace", "no workspace"),
        ('goal: ["On(body, region3)"]', 'goal: ["On(body, region2)"]', "goal[0]", "no Sample-pose"),
    ],
)
def test_a_mistake_names_the_file_and_the_field(
    tmp_path: Path, old: str, new: str, field: str, words: str
) -> None:
    assert old in GOOD
    path = tmp_path / "broken.yaml"
    path.write_text(GOOD.replace(old, new))
    with pytest.raises(TaskError) as err:
        load_task(str(path))
    message = str(err.value)
    assert message.startswith(f"{path}: {field}: ")
    assert words in message


def test_unknown_task_name_and_bad_yaml_are_clear(tmp_path: Path) -> None:
    with pytest.raises(TaskError, match="no such task"):
        load_task("desks")
    path = tmp_path / "bad.yaml"
    path.write_text("task: [unclosed\n")
    with pytest.raises(TaskError, match=r"bad\.yaml: line \d+: not valid YAML"):
        load_task(str(path))

"""Predecessors in task files: shipped names and relative paths resolved, mistakes refused;
suite directories read by role; geometry warnings for regions that cannot work."""

from __future__ import annotations

from pathlib import Path

import pytest

from cpkb.bench.scenarios import Scenario, expand, predecessors
from planner.tasks import load_task
from planner.tasks.loader import data_dir
from planner.tasks.schema import TaskError
from planner.tasks.suites import suite_targets

PICK_PLACE = """\
task: {name}
workspace: {workspace}
{extra}
obstacles: [obstacle1]
bodies:
  body: {{size: {size}, pose: pose0}}
skeleton:
  - decision: "Sample-grasp(body) -> #dir1"
  - transition:
      - "Inv-kin(body, pose0, #dir1) -> #config1"
      - "Plan-motion(config0, #config1) -> #traj01"
      - "Move-Pick(body, #traj01)"
  - decision: "Sample-pose(body, {region}) -> #pose13"
  - transition:
      - "Inv-kin(body, #pose13, #dir1) -> #config3"
      - "Plan-motion(#config1, #config3) -> #traj13"
      - "Move-Place(body, #traj13)"
goal: ["On(body, {region})"]
"""


def write_task(
    path: Path,
    extra: str = "",
    *,
    region: str = "region3",
    size: str = "[0.06, 0.06, 0.16]",
    workspace: str = "tabletop",
) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        PICK_PLACE.format(
            name=path.stem, extra=extra, region=region, size=size, workspace=workspace
        )
    )
    return path


def test_the_shipped_chains_are_declared_in_the_task_files() -> None:
    assert load_task("desk").predecessors == ("deskP",)
    assert load_task("regrasp").predecessors == ("deskP", "desk")
    assert load_task("pack").predecessors == ("packP1", "packP2", "packP3")
    assert load_task("deskP").predecessors == ()
    assert Scenario("regrasp", "cp-bo-transfer", 0).predecessors == ("deskP", "desk")
    # The analytic worlds follow the shipped task of their name.
    assert predecessors("analytic:desk") == ("analytic:deskP",)
    assert predecessors("analytic:deskP") == ()


def test_names_and_relative_paths_resolve(tmp_path: Path) -> None:
    other = write_task(tmp_path / "other" / "warmup.yaml")
    target = write_task(
        tmp_path / "mine" / "target.yaml", "predecessors: [deskP, ../other/warmup.yaml]"
    )
    task = load_task(str(target))
    assert task.predecessors == ("deskP", str(other.resolve()))
    # The bench runs exactly those, for a task file as for a shipped task.
    assert predecessors(str(target)) == task.predecessors
    scenarios = expand([str(target)], ["cp-bo-transfer"], range(1))
    assert scenarios[0].predecessors == ("deskP", str(other.resolve()))


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        ("predecessors: [deskQ]", "no shipped task 'deskQ'"),
        ("predecessors: [missing.yaml]", "no task file 'missing.yaml'"),
        ("predecessors: deskP", "expected a list"),
        ("predecessors: [deskP, deskP]", "named twice"),
        ("role: boss", "expected one of target, predecessor"),
    ],
)
def test_a_bad_predecessor_is_a_clear_error(tmp_path: Path, extra: str, words: str) -> None:
    path = write_task(tmp_path / "t.yaml", extra)
    with pytest.raises(TaskError) as err:
        load_task(str(path))
    assert str(err.value).startswith(f"{path}: ")
    assert words in str(err.value)


def test_cycles_are_refused(tmp_path: Path) -> None:
    write_task(tmp_path / "a.yaml", "predecessors: [b.yaml]")
    write_task(tmp_path / "b.yaml", "predecessors: [c.yaml]")
    write_task(tmp_path / "c.yaml", "predecessors: [a.yaml]")
    with pytest.raises(
        TaskError, match=r"predecessors form a cycle: a\.yaml -> b\.yaml -> c\.yaml"
    ):
        load_task(str(tmp_path / "a.yaml"))
    write_task(tmp_path / "self.yaml", "predecessors: [self.yaml]")
    with pytest.raises(TaskError, match=r"cycle: self\.yaml -> self\.yaml"):
        load_task(str(tmp_path / "self.yaml"))


def test_a_task_without_predecessors_cannot_be_transferred_to(tmp_path: Path) -> None:
    path = write_task(tmp_path / "alone.yaml")
    with pytest.raises(ValueError, match="no predecessor tasks"):
        expand([str(path)], ["cp-bo-transfer"], range(1))


def test_a_suite_directory_lists_its_targets(tmp_path: Path) -> None:
    write_task(tmp_path / "marked" / "pre.yaml", "role: predecessor")
    write_task(tmp_path / "marked" / "t.yaml", "role: target\npredecessors: [pre.yaml]")
    (tmp_path / "marked" / "suite.yaml").write_text("seed: 1\n")  # not a task: skipped
    assert suite_targets(tmp_path / "marked") == [tmp_path / "marked" / "t.yaml"]
    # Without roles, a file some other file names as a predecessor is not a target.
    write_task(tmp_path / "plain" / "pre.yaml")
    write_task(tmp_path / "plain" / "t1.yaml", "predecessors: [pre.yaml]")
    write_task(tmp_path / "plain" / "t2.yaml", "predecessors: [pre.yaml, deskP]")
    assert suite_targets(tmp_path / "plain") == [
        tmp_path / "plain" / "t1.yaml",
        tmp_path / "plain" / "t2.yaml",
    ]
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(TaskError, match="no task files"):
        suite_targets(empty)


def test_shipped_tasks_have_no_warnings_and_bad_geometry_is_named(tmp_path: Path) -> None:
    assert all(load_task(n).warnings == () for n in ("deskP", "desk", "regrasp", "pack"))
    wide = load_task(str(write_task(tmp_path / "wide.yaml", size="[0.05, 0.25, 0.1]")))
    assert len(wide.warnings) == 1
    assert "region3 (0.200 x 0.200 m) cannot hold body (0.250 m" in wide.warnings[0]
    workspace = (data_dir() / "workspaces" / "tabletop.yaml").read_text()
    far = workspace.replace(
        "  region3: {center: [0.36, 0.0, 0.0], size: [0.2, 0.2]}",
        "  region3: {center: [0.9, 0.3, 0.0], size: [0.2, 0.2]}",
    )
    assert far != workspace
    (tmp_path / "far_ws.yaml").write_text(far)
    task = load_task(str(write_task(tmp_path / "far.yaml", workspace="far_ws.yaml")))
    assert len(task.warnings) == 1
    assert (
        "part of region3 lies" in task.warnings[0]
        and "beyond the Panda's 0.855 m reach" in (task.warnings[0])
    )

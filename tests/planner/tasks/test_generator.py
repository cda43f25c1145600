"""Generated suites: reproducible from the seed, every target loads with its predecessors, and
a checked suite is solved by quasi-random (real PyBullet DIRECT) with the seeds it records."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from planner.run import run_plan
from planner.tasks import load_task
from planner.tasks.generator import ProbeSettings, generate_suite
from planner.tasks.generator.suite import passes
from planner.tasks.suites import suite_targets

UNCHECKED = ProbeSettings(check=False)


def _texts(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): p.read_text() for p in sorted(root.rglob("*.yaml"))}


@pytest.mark.slow
def test_the_same_seed_writes_the_same_suite_and_another_seed_another(tmp_path: Path) -> None:
    generate_suite(tmp_path / "a", 2, seed=11, settings=UNCHECKED)
    generate_suite(tmp_path / "b", 2, seed=11, settings=UNCHECKED)
    generate_suite(tmp_path / "c", 2, seed=12, settings=UNCHECKED)
    first = _texts(tmp_path / "a")
    assert len(first) == 1 + 2 * 9  # the index; per workspace, its file and 8 tasks
    assert first == _texts(tmp_path / "b")
    other = _texts(tmp_path / "c")
    assert first["ws00/workspace.yaml"] != other["ws00/workspace.yaml"]


@pytest.mark.slow
def test_targets_and_predecessors_share_obstacles_but_are_not_copies(tmp_path: Path) -> None:
    generate_suite(tmp_path, 3, seed=5, settings=UNCHECKED)
    targets = suite_targets(tmp_path)
    assert [p.relative_to(tmp_path).as_posix() for p in targets] == [
        f"ws{i:02d}/{k}.yaml" for i in range(3) for k in ("desk", "pack", "regrasp")
    ]
    for path in targets:
        target = load_task(str(path))
        assert target.role == "target" and target.warnings == ()
        assert target.predecessors
        for pre_path in target.predecessors:
            pre = load_task(pre_path)
            assert Path(pre_path).parent == path.parent.resolve()
            assert pre.role == "predecessor" and pre.kind == target.kind
            assert set(target.obstacles) <= set(pre.obstacles)
            same = {b: (v.size, v.pose) for b, v in pre.bodies.items()} == {
                b: (v.size, v.pose) for b, v in target.bodies.items()
            } and pre.goal == target.goal
            assert not same, f"{pre_path} copies {path}"
        if target.kind == "pack":
            assert 2 <= len(target.bodies) <= 4


def test_probe_verdicts() -> None:
    settings = ProbeSettings(seeds=3, trivial=3)
    assert passes([40, None, 120], settings)
    assert not passes([40, None, None], settings)
    assert not passes([2, 3, 9], settings)  # median 3: a handful of rollouts is trivial


@pytest.mark.slow
def test_a_checked_suite_is_solved_by_quasi_random(tmp_path: Path) -> None:
    settings = ProbeSettings(seeds=1, max_rollouts=300)
    made = generate_suite(tmp_path, 1, seed=2, settings=settings)
    index = yaml.safe_load((tmp_path / "suite.yaml").read_text())
    assert index["check"]["enabled"] and len(index["targets"]) == 3 == len(made["targets"])
    for entry in index["targets"]:
        (rollouts,), (seed,) = entry["probe_rollouts"], entry["probe_seeds"]
        assert 3 < rollouts <= 300
        result = run_plan(str(tmp_path / entry["file"]), "quasi-random", seed, max_rollouts=300)
        assert result.solved, entry

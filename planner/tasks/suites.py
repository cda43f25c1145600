"""A directory of task files as a suite: which of its tasks are targets.

A file with `role: target` is one; where no file declares a role, every task file that no
other file of the directory names as a predecessor is one. Files without `bodies` and a
`goal` (a workspace, the suite's index) are not tasks; a task may leave out its skeleton.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from planner.tasks.loader import load_task_file
from planner.tasks.schema import Task, TaskError


def _is_task_file(path: Path) -> bool:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return True  # loading it names the problem
    return isinstance(data, dict) and "bodies" in data and "goal" in data


def suite_tasks(directory: Path) -> dict[Path, Task]:
    """Every task file under `directory`, loaded (a broken one raises `TaskError`)."""
    if not directory.is_dir():
        raise TaskError(f"{directory}: not a directory")
    files = sorted(p for p in directory.rglob("*") if p.suffix in (".yaml", ".yml"))
    return {p: load_task_file(p) for p in files if _is_task_file(p)}


def suite_targets(directory: Path) -> list[Path]:
    """The target task files of a suite directory, in path order."""
    tasks = suite_tasks(directory)
    if not tasks:
        raise TaskError(f"{directory}: no task files (YAML with `bodies` and a `goal`) in it")
    if any(t.role is not None for t in tasks.values()):
        return [p for p, t in tasks.items() if t.role == "target"]
    named = {Path(p) for t in tasks.values() for p in t.predecessors if "/" in p}
    return [p for p in tasks if p.resolve() not in named]

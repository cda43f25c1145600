"""The PyBullet world: a task's scene, the Panda, IK, OMPL motion planning and the operators.

`load_world("desk", seed=0)` gives a `BindingWorld` (see `planner.world`) for a shipped task
name or a task file path; DIRECT by default, `gui=True` opens PyBullet's window.
"""

from __future__ import annotations

from pathlib import Path

from planner.sim.world import PyBulletWorld, SimState
from planner.tasks import load_task

__all__ = ["PyBulletWorld", "SimState", "load_world"]


def load_world(task: str | Path, *, seed: int, gui: bool = False) -> PyBulletWorld:
    """A world for a shipped task (`"desk"`) or a task file (`"my_task.yaml"`)."""
    return PyBulletWorld(load_task(task), seed=seed, gui=gui)

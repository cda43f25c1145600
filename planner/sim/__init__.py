"""The PyBullet world: a task's scene, the Panda, IK, OMPL motion planning and the operators.

`load_world("desk", seed=0)` gives a `BindingWorld` (see `planner.world`) for a shipped task
name or a task file path; DIRECT by default, `gui=True` opens PyBullet's window.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from pathlib import Path


def _import_pybullet_quietly() -> None:
    """PyBullet prints a build-time banner from C when imported (to stderr, in this build): on a
    terminal it breaks the progress line and leaves a stale one. So the first import runs with
    file descriptors 1 and 2 on /dev/null (C's buffers flushed there before they come back)."""
    if "pybullet" in sys.modules:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(fd) for fd in (1, 2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            os.dup2(devnull, fd)
        import pybullet  # noqa: F401

        with contextlib.suppress(OSError, AttributeError, TypeError):  # no C library: Windows
            ctypes.CDLL(None).fflush(None)
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


_import_pybullet_quietly()

from planner.sim.world import PyBulletWorld, SimState  # noqa: E402
from planner.tasks import load_task  # noqa: E402

__all__ = ["PyBulletWorld", "SimState", "load_world"]


def load_world(task: str | Path, *, seed: int, gui: bool = False) -> PyBulletWorld:
    """A world for a shipped task (`"desk"`) or a task file (`"my_task.yaml"`)."""
    return PyBulletWorld(load_task(task), seed=seed, gui=gui)

"""`cpkb render`: the camera option, and the arm sent home after a binding is executed."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cpkb.cli.world import DEFAULT_TARGET, _camera, _park_arm


def test_camera_takes_three_or_six_numbers() -> None:
    camera = _camera("-120,-30,1.6")
    assert (camera.yaw, camera.pitch, camera.distance) == (-120, -30, 1.6)
    assert camera.target == DEFAULT_TARGET
    assert _camera("10,-20,2,0.4,0.1,0.2").target == (0.4, 0.1, 0.2)
    for bad in ("1,2", "a,b,c", "1,2,0", "1,2,3,4"):
        with pytest.raises(argparse.ArgumentTypeError):
            _camera(bad)


@pytest.mark.slow
def test_the_arm_goes_home_carrying_what_it_holds() -> None:
    from planner.sim import load_world
    from planner.sim.grasps import carried_pose
    from planner.sim.render import replay

    world = load_world("desk", seed=0)
    try:
        outcomes = replay(world, {"#dir1": "front"})
        assert outcomes and outcomes[-1].ok  # the pick: the box is held
        held = outcomes[-1].state.held
        assert held is not None
        _park_arm(world, outcomes)
        scene = world.scene
        home = scene.task.workspace.robot.home
        assert np.allclose(scene.arm(), home, atol=1e-6)
        expected = carried_pose(scene, held)
        assert np.allclose(scene.pose(held.body)[0], expected[0], atol=1e-6)
    finally:
        world.close()


@pytest.mark.slow
def test_a_camera_changes_the_picture(tmp_path: Path) -> None:
    def render(*extra: str) -> bytes:
        out = tmp_path / f"scene{len(extra)}.png"
        done = subprocess.run(
            [sys.executable, "-m", "cpkb", "render", "--task", "desk", "--out", str(out), *extra],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, done.stderr
        return out.read_bytes()

    default, turned = render(), render("--camera=-60,-40,1.8")
    assert turned[:8] == b"\x89PNG\r\n\x1a\n" and turned != default

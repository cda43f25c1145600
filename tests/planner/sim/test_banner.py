"""PyBullet's build-time banner stays out of the terminal: it broke the progress line."""

from __future__ import annotations

import subprocess
import sys


def test_importing_the_simulator_prints_no_banner() -> None:
    code = "import planner.sim, pybullet; print('imported')"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "imported\n"
    assert "pybullet build time" not in done.stderr

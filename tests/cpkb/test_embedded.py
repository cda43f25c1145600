"""The embedded service of `cpkb plan` and `cpkb bench`: on the cores its planners leave."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cpkb.embedded import embedded_service

pytestmark = [
    pytest.mark.skipif(
        not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
        reason="needs Linux CPU affinity and two cores",
    ),
    pytest.mark.slow,
]


def _service_cores(url: str) -> set[int]:
    """The cores of the `cpkb serve` process listening at `url`."""
    port = url.rsplit(":", 1)[1]
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"serve" in argv and port.encode() in argv:
            return os.sched_getaffinity(int(pid))
    raise AssertionError(f"no cpkb serve process on port {port}")


def test_the_service_keeps_off_the_planners_cores(tmp_path: Path) -> None:
    allowed = sorted(os.sched_getaffinity(0))
    with embedded_service(f"sqlite:///{tmp_path / 'kb.db'}", planner_cores=1) as url:
        assert _service_cores(url) == set(allowed[1:])
    with embedded_service(f"sqlite:///{tmp_path / 'kb.db'}") as url:
        assert _service_cores(url) == set(allowed)


def test_cpkb_cpu_cores_given_to_it_wins(tmp_path: Path) -> None:
    first = min(os.sched_getaffinity(0))
    env = {"CPKB_CPU_CORES": str(first)}
    with embedded_service(f"sqlite:///{tmp_path / 'kb.db'}", env=env, planner_cores=1) as url:
        assert _service_cores(url) == {first}

"""`cpkb bindings` lists the binding lists planners found (a real server)."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_support import cpkb_in_process
from service_support import run_live_server

from client import CpkbClient
from contract.bindings import BindingIn


@pytest.mark.slow
def test_bindings_lists_what_planners_found_and_refuses_a_bad_limit(
    db_url: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    with run_live_server(db_url, tmp_path / "server.log") as server, CpkbClient(server.url) as c:
        empty = cpkb_in_process(capfd, "bindings", "--url", server.url)
        for task, grasp in (("desk", "front"), ("pack", "top")):
            found = {"#dir1": grasp, "#pose12": [0.21, 0.8, 0.5]}
            c.add_binding(
                "default",
                BindingIn(
                    task=task, skeleton="s" * 64, run=f"{task}-7", rollout=12, bindings=found
                ),
            )
        desk = cpkb_in_process(capfd, "bindings", "--task", "desk", "--url", server.url)
        bad = cpkb_in_process(capfd, "bindings", "--limit", "0", "--url", server.url)
    assert empty.returncode == 0 and "no found bindings" in empty.stdout
    assert desk.returncode == 0, desk.stderr
    row = next(line for line in desk.stdout.splitlines() if "desk-7" in line)
    assert "#dir1=front" in row and "#pose12=[0.21, 0.8, 0.5]" in row and "12" in row
    assert "pack" not in desk.stdout
    assert bad.returncode != 0 and "--limit" in bad.stderr and "Traceback" not in bad.stderr

"""What a new user meets first (issue 56.8): `cpkb serve` prints the URL it serves, `plan`'s
binding line stays one line when piped, `generate` names an unsolved probe, `make bench` is a
taste, not the 1,500-run evaluation."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from cpkb.cli.service import served_url
from cpkb.embedded import free_port, stop_process
from planner.tasks.generator.suite import ProbeSettings, probe_text

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_serve_prints_a_url_that_opens_the_dashboard(tmp_path: Path) -> None:
    port = free_port()
    command = [sys.executable, "-m", "cpkb", "serve", "--port", str(port)]
    command += ["--db", f"sqlite:///{tmp_path / 'kb.db'}"]
    server = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert server.stdout is not None
        line = server.stdout.readline()
        found = re.search(r"at (http://\S+/) \(the dashboard", line)
        assert found, line
        assert found.group(1) == f"http://127.0.0.1:{port}/"
        page = httpx.get(found.group(1), timeout=60)
        assert page.status_code == 200 and "cpkb" in page.text
    finally:
        stop_process(server)


def test_a_wildcard_address_is_served_at_loopback() -> None:
    assert served_url("0.0.0.0", 8000) == "http://127.0.0.1:8000/"
    assert served_url("::", 8000) == "http://[::1]:8000/"
    assert served_url("::1", 80) == "http://[::1]:80/"
    assert served_url("kb.lab", 8000) == "http://kb.lab:8000/"


@pytest.mark.slow
def test_plans_binding_line_is_one_json_line_when_piped() -> None:
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "cpkb",
            "plan",
            "--task",
            "analytic:desk",
            "--method",
            "quasi-random",
            "--quiet",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stdout.splitlines() if line.startswith("bindings: ")]
    assert len(lines) == 1
    bindings = json.loads(lines[0].removeprefix("bindings: "))
    assert isinstance(bindings, dict) and bindings
    assert len(lines[0]) > 80  # long enough that rich would have wrapped it


def test_an_unsolved_probe_is_named_not_none() -> None:
    text = probe_text([12, None, 40], ProbeSettings(max_rollouts=500))
    assert text == "quasi-random rollouts 12, unsolved in 500, 40"
    assert "None" not in text


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_make_bench_is_a_small_run_by_default() -> None:
    out = subprocess.run(
        ["make", "-n", "-o", "setup", "bench"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    line = next(line for line in out.stdout.splitlines() if "cpkb bench" in line)
    assert "--seeds 5" in line and "--tasks desk" in line

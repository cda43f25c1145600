"""`cpkb generate` writes a suite, and `cpkb bench --tasks DIR` runs its targets, with
cp-bo-transfer running each target's declared predecessors first (real embedded service, real
PyBullet DIRECT)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cli_support import cpkb_in_process

from planner.tasks import load_task


def cpkb(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cpkb", *args], capture_output=True, text=True, timeout=1800
    )


def test_generate_refuses_bad_arguments(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    out = cpkb_in_process(capfd, "generate", "--out", str(tmp_path / "s"), "--workspaces", "0")
    assert out.returncode == 2 and "must be at least 1, got 0" in out.stderr
    (tmp_path / "file").write_text("")
    out = cpkb_in_process(capfd, "generate", "--out", str(tmp_path / "file"), "--no-check")
    assert out.returncode == 2 and "is not a directory" in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.slow
def test_bench_on_a_task_file_without_predecessors_is_a_clear_error(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    suite = tmp_path / "suite"
    made = cpkb_in_process(
        capfd, "generate", "--out", str(suite), "--seed", "3", "--no-check", "--workspaces", "1"
    )
    assert made.returncode == 0, made.stderr
    pre = str(suite / "ws00" / "desk_pre.yaml")
    out = cpkb_in_process(
        capfd, "bench", "--tasks", pre, "--methods", "cp-bo-transfer", "--out", str(tmp_path / "b")
    )
    assert out.returncode == 2 and "no predecessor tasks" in out.stderr


@pytest.mark.slow
def test_a_transfer_bench_over_a_generated_suite_completes(tmp_path: Path) -> None:
    suite, out = tmp_path / "suite", tmp_path / "bench"
    made = cpkb("generate", "--out", str(suite), "--workspaces", "1", "--seed", "3", "--no-check")
    assert made.returncode == 0, made.stderr
    assert "wrote 3 targets in 1 workspaces" in made.stdout
    bench = cpkb(
        "bench", "--tasks", str(suite), "--methods", "cp-bo-transfer", "--seeds", "1",
        "--workers", "1", "--max-rollouts", "15", "--predecessor-rollouts", "4",
        "--out", str(out), "--quiet",
    )  # fmt: skip
    assert bench.returncode == 0, bench.stdout + bench.stderr
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert sorted(Path(r["task"]).name for r in runs) == ["desk.yaml", "pack.yaml", "regrasp.yaml"]
    for run in runs:
        declared = load_task(run["task"]).predecessors
        assert [p["task"] for p in run["predecessors"]] == list(declared)
        assert all(p["rollouts_spent"] == 4 for p in run["predecessors"])
        assert run["method"] == "cp-bo-transfer" and run["sampler"] == "cp-bo"


@pytest.mark.slow
def test_generate_draws_the_hard_family(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    suite = tmp_path / "hard"
    argv = ["--out", str(suite), "--seed", "5", "--no-check", "--workspaces", "1"]
    made = cpkb_in_process(capfd, "generate", "--difficulty", "hard", *argv)
    assert made.returncode == 0, made.stderr
    assert "wrote 1 targets in 1 workspaces" in made.stdout
    target = load_task(str(suite / "ws00" / "tight_pack.yaml"))
    assert target.kind == "tight-pack" and 5 <= len(target.bodies) <= 8

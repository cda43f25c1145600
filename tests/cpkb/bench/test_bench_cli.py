"""`cpkb bench` from the command line: clear errors, and a real run on the analytic desk."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from wait_support import PATIENCE_S, wait_until

from cpkb.cli import main


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seeds", "0"], "must be at least 1, got 0"),
        (["--workers", "two"], "not a whole number: 'two'"),
        (["--time-limit", "5x"], "not a duration"),
        (["--methods", "cp-bo,cp-bo"], "a name is repeated"),
        (["--tasks", "analytic:desk", "--methods", "cp-bo,nope"], "unknown method 'nope'"),
        (["--tasks", "nosuch", "--methods", "cp-bo"], "unknown task 'nosuch'"),
        (["--tasks", "missing/task.yaml", "--methods", "cp-bo"], "no such task file"),
        (["--tasks", "analytic:deskP", "--methods", "cp-bo-transfer"], "no predecessor tasks"),
        (["--tasks", "desk,pack", "--methods", "cp-bo", "--mixed"], "--mixed needs --concurrent"),
        (["--cores", "0"], "must be at least 1, got 0"),
        (["--cores", "1", "--workers", "2", "--methods", "cp-bo"], "use --workers 1"),
        (["--cores", "100000", "--methods", "cp-bo"], "may use only"),
    ],
)
def test_bad_arguments_are_one_line_errors(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        code = main(["bench", "--out", str(tmp_path / "out"), *argv])
        raise SystemExit(code)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.slow
def test_a_small_real_bench_runs_resumes_and_reports(tmp_path: Path) -> None:
    out = tmp_path / "out"
    command = [
        sys.executable, "-m", "cpkb", "bench", "--tasks", "analytic:desk",
        "--methods", "quasi-random,cp-bo-transfer", "--seeds", "1", "--workers", "2",
        "--max-rollouts", "300", "--out", str(out), "--quiet",
    ]  # fmt: skip
    first = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stdout + first.stderr
    assert "2 runs finished, 0 already done, 0 failed, 0 left" in first.stdout
    runs = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert sorted((r["method"], r["seed"]) for r in runs) == [
        ("cp-bo-transfer", 0), ("quasi-random", 0)
    ]  # fmt: skip
    transfer = [r for r in runs if r["method"] == "cp-bo-transfer"]
    assert all(r["predecessors"][0]["task"] == "analytic:deskP" for r in transfer)
    assert all(r["predecessors"][0]["rollouts_spent"] == 30 for r in transfer)
    assert all(r["solved"] for r in runs)
    for name in ("summary.md", "summary.csv", "rollouts.png", "wall_time.png"):
        assert (out / name).stat().st_size > 0
    assert "| analytic:desk | cp-bo-transfer | 1 |" in (out / "summary.md").read_text()

    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "0 runs finished, 2 already done" in again.stdout
    summary = subprocess.run(
        [*command[:4], "--tasks", "analytic:desk", "--out", str(out), "--summary-only"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert summary.returncode == 0 and "cp-bo-transfer" in summary.stdout


def _children(pid: int) -> list[int]:
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads processes from /proc")
def test_a_terminated_bench_stops_its_embedded_service(tmp_path: Path) -> None:
    """`kill` (SIGTERM) on a bench unwinds like Ctrl-C: it reports what it has, and its
    embedded service and its workers stop with it instead of running on."""
    out = tmp_path / "out"
    command = [
        sys.executable, "-m", "cpkb", "bench", "--tasks", "analytic:desk",
        "--methods", "cp-bo-transfer", "--seeds", "50", "--workers", "1",
        "--out", str(out), "--quiet",
    ]  # fmt: skip
    bench = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:

        def first_run_recorded() -> bool:
            assert bench.poll() is None, bench.stderr.read()
            runs = out / "runs.jsonl"
            return runs.is_file() and bool(runs.read_text())

        wait_until(first_run_recorded, timeout=2 * PATIENCE_S, interval=0.2, what="a first run")
        children = _children(bench.pid)
        assert len(children) >= 2  # the service and the pool's worker
        bench.send_signal(signal.SIGTERM)
        stdout, _ = bench.communicate(timeout=PATIENCE_S)
        assert bench.returncode == 1  # runs are left: a rerun continues
        assert "(interrupted: rerun the same command to continue)" in stdout
    finally:
        if bench.poll() is None:
            bench.kill()
    wait_until(
        lambda: not any(_alive(pid) for pid in children),
        interval=0.2,
        what="the bench's service and workers stopping",
    )

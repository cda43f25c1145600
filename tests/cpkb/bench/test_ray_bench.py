"""`cpkb bench --ray`: the runs as tasks on a real local Ray head, the same results and resume
as the local pool, and a clear error without Ray."""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from wait_support import wait_until

from client import CpkbClient
from cpkb.cli import main
from cpkb.embedded import embedded_service, free_port

RAY_BIN = Path(sys.executable).with_name("ray")
HAS_RAY = importlib.util.find_spec("ray") is not None
NO_RAY = "ray is not installed (pip install -e '.[ray]')"
# Ray otherwise swaps 127.0.0.1 for the machine's outward address; the test stays on loopback.
LOOPBACK_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}
# One seed per method: a run per worker and per Ray CPU, enough to compare with the local pool;
# more seeds would only lengthen the deterministic cp-bo runs.
BENCH = [
    *("--tasks", "analytic:desk", "--methods", "quasi-random,cp-bo", "--seeds", "1"),
    *("--max-rollouts", "300", "--deterministic", "--quiet"),
]


def _ours(temp_dir: Path) -> list[int]:
    """The pids of the processes of the head started on `temp_dir` (every Ray process of a
    node names its temp dir on its command line)."""
    pids = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            if str(temp_dir).encode() in cmdline.read_bytes():
                pids.append(int(cmdline.parent.name))
        except (OSError, ValueError):
            continue
    return pids


@pytest.fixture(scope="module")
def ray_head(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A one-node Ray cluster on loopback, off port 6379, stopped (only it) at the end."""
    if not HAS_RAY:
        pytest.skip(NO_RAY)
    temp_dir = tmp_path_factory.mktemp("ray")
    address = f"127.0.0.1:{free_port()}"
    ports = {
        "--ray-client-server-port": free_port(),
        "--dashboard-port": free_port(),
        "--dashboard-agent-listen-port": free_port(),
    }
    command = [
        *(str(RAY_BIN), "start", "--head", "--block", "--node-ip-address", "127.0.0.1"),
        *("--port", address.rsplit(":", 1)[1], "--num-cpus", "2", "--num-gpus", "0"),
        *("--include-dashboard=false", "--disable-usage-stats", "--temp-dir", str(temp_dir)),
        *("--object-store-memory", str(100 * 1024 * 1024)),
        *(str(item) for pair in ports.items() for item in pair),
    ]
    env = {**os.environ, **LOOPBACK_ENV, "RAY_ADDRESS": address}
    log = (temp_dir / "head.log").open("wb")
    head = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env)
    try:
        wait_until(
            lambda: (
                head.poll() is not None
                or subprocess.run(
                    [str(RAY_BIN), "status", "--address", address], env=env, capture_output=True
                ).returncode
                == 0
            ),
            interval=1.0,
            what="the Ray head to start",
        )
        assert head.poll() is None, (temp_dir / "head.log").read_text()
        yield address
    finally:
        head.send_signal(signal.SIGTERM)  # `ray start --block` stops its node's processes
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            head.kill()
        log.close()
        for pid in _ours(temp_dir):  # workers left behind, if any: ours by their temp dir
            os.kill(pid, signal.SIGKILL)


def _bench(out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "cpkb", "bench", *BENCH, "--out", str(out), *extra]
    env = {**os.environ, **LOOPBACK_ENV}
    return subprocess.run(command, capture_output=True, text=True, timeout=600, env=env)


def _runs(out: Path) -> dict[tuple[str, int], dict]:
    lines = (out / "runs.jsonl").read_text().splitlines()
    return {(r["method"], r["seed"]): r for r in map(json.loads, lines)}


@pytest.fixture(scope="module")
def local_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, int], dict]:
    """The same bench on the local pool, to compare with."""
    if not HAS_RAY:
        pytest.skip(NO_RAY)
    out = tmp_path_factory.mktemp("local") / "out"
    done = _bench(out, "--workers", "2")
    assert done.returncode == 0, done.stdout + done.stderr
    return _runs(out)


@pytest.mark.slow
def test_ray_runs_match_the_local_pool_and_resume(
    ray_head: str, local_runs: dict, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    first = _bench(out, "--ray", ray_head)
    assert first.returncode == 0, first.stdout + first.stderr
    assert "2 runs finished, 0 already done, 0 failed, 0 left" in first.stdout
    runs = _runs(out)
    assert set(runs) == set(local_runs)
    assert os.getpid() not in {r["worker_pid"] for r in runs.values()}
    # Seeded runs on fresh knowledge bases repeat, wherever they run.
    assert {k: r["rollouts"] for k, r in runs.items()} == {
        k: r["rollouts"] for k, r in local_runs.items()
    }
    assert all(r["points_posted"] > 0 for k, r in runs.items() if k[0] == "cp-bo")
    for name in ("summary.md", "summary.csv", "rollouts.png", "wall_time.png"):
        assert (out / name).stat().st_size > 0

    again = _bench(out, "--ray", ray_head)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "0 runs finished, 2 already done" in again.stdout
    assert len((out / "runs.jsonl").read_text().splitlines()) == 2


@pytest.mark.slow
def test_ray_runs_use_a_shared_service_and_leave_it_clean(
    ray_head: str, local_runs: dict, tmp_path: Path
) -> None:
    db = tmp_path / "shared.db"
    with embedded_service(f"sqlite:///{db}") as url:
        done = _bench(tmp_path / "out", "--ray", ray_head, "--kb-url", url)
        assert done.returncode == 0, done.stdout + done.stderr
        with CpkbClient(url) as client:
            assert [kb.name for kb in client.list_kbs()] == ["default"]
    runs = _runs(tmp_path / "out")
    assert {k: r["rollouts"] for k, r in runs.items()} == {
        k: r["rollouts"] for k, r in local_runs.items()
    }


def test_ray_missing_is_a_usage_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now fails as if not installed
    code = main(["bench", *BENCH, "--out", str(tmp_path / "out"), "--ray", "127.0.0.1:1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--ray needs Ray" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not HAS_RAY, reason=NO_RAY)
def test_concurrent_groups_are_refused_on_ray(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["bench", *BENCH, "--out", str(tmp_path / "out"), "--ray", "127.0.0.1:1"]
    assert main([*argv, "--concurrent", "2"]) == 2
    assert "not with --ray" in capsys.readouterr().err


@pytest.mark.skipif(not HAS_RAY, reason=NO_RAY)
def test_an_unreachable_head_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    address = f"127.0.0.1:{free_port()}"  # nothing listens there
    assert main(["bench", *BENCH, "--out", str(tmp_path / "out"), "--ray", address]) == 2
    assert f"no Ray head answers at {address}" in capsys.readouterr().err

"""`cpkb serve`, `cpkb kb ...`, `cpkb types`: a real server, restarted, seen through the CLI."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from cli_support import cpkb_in_process
from service_support import make_graph, make_point, run_live_server

from client import CpkbClient
from cpkb.embedded import START_TIMEOUT_S, free_port, stop_process, wait_ready


def cpkb(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cpkb", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
    )


@pytest.mark.slow
def test_points_survive_a_restart_and_show_in_cpkb_types(
    db_url: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    def cli(*args: str) -> subprocess.CompletedProcess[str]:
        return cpkb_in_process(capfd, *args)

    log = tmp_path / "server.log"
    graphs = [make_graph(), make_graph(failure="Plan-motion", context=("shelf", "box2"))]
    with run_live_server(db_url, log) as server, CpkbClient(server.url) as client:
        client.create_kb("lab")
        posted = client.post_points("lab", [make_point(i, graph=graphs[i % 2]) for i in range(30)])
        before = {t.type_id: t.n_points for t in client.list_types("lab")}
        points_before = {t: list(client.iter_points("lab", t)) for t in before}

    with run_live_server(db_url, log) as server:
        with CpkbClient(server.url) as client:
            assert {t.type_id: t.n_points for t in client.list_types("lab")} == before
            assert {t: list(client.iter_points("lab", t)) for t in before} == points_before
            assert sorted(r.point_id for r in posted) == sorted(
                p.point_id for ps in points_before.values() for p in ps
            )
        table = cli("types", "--kb", "lab", "--kb-url", server.url)
        assert table.returncode == 0, table.stderr
        assert "Plan-motion" in table.stdout and "Inv-kin" in table.stdout
        assert "box2" in table.stdout and "15" in table.stdout
        for type_id in before:
            assert type_id in table.stdout

        assert cli("kb", "create", "scratch", "--url", server.url).returncode == 0
        listing = cli("kb", "list", "--url", server.url)
        assert "scratch" in listing.stdout and "lab" in listing.stdout and "30" in listing.stdout
        assert cli("kb", "delete", "scratch", "--url", server.url).returncode == 0
        assert "scratch" not in cli("kb", "list", "--url", server.url).stdout

        # the service refused the request: the README's exit 3, as plan and bench give
        unknown = cli("types", "--kb", "nope", "--url", server.url)
        assert unknown.returncode == 3
        assert unknown.stderr.strip().splitlines() == [
            f"cpkb types: error: the knowledge base at {server.url} answered 404 GET "
            "/v1/kbs/nope/types: knowledge base 'nope' not found"
        ]
        taken = cli("kb", "create", "lab", "--url", server.url)
        assert taken.returncode == 3 and "already exists" in taken.stderr


@pytest.mark.parametrize(
    "command",
    [("types",), ("kb", "list"), ("kb", "create", "x"), ("kb", "delete", "x"), ("bindings",)],
)
def test_unreachable_server_is_one_line_exit_3_for_every_command(
    command: tuple[str, ...], capfd: pytest.CaptureFixture[str]
) -> None:
    out = cpkb_in_process(capfd, *command, "--url", f"http://127.0.0.1:{free_port()}")
    assert out.returncode == 3, out.stderr
    assert out.stderr.count("\n") == 1 and "cannot reach the knowledge base" in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.slow
def test_serve_with_a_bad_database_is_one_line_exit_2(tmp_path: Path) -> None:
    for url in ("mysql://nobody@127.0.0.1/x", "postgresql+psycopg://postgres@127.0.0.1:1/x"):
        out = cpkb("serve", "--db", url, "--port", str(free_port()), cwd=tmp_path)
        assert out.returncode == 2, out.stderr
        assert out.stderr.startswith("cpkb serve: error: ") and "Traceback" not in out.stderr


def test_serve_on_a_port_in_use_fails_before_touching_the_database(tmp_path: Path) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        db = tmp_path / "kb.sqlite"
        out = cpkb("serve", "--db", f"sqlite:///{db}", "--port", str(port), cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert f"cannot listen on 127.0.0.1:{port}" in out.stderr and "in use" in out.stderr
    assert "serving" not in out.stdout
    assert not db.exists()


@pytest.mark.skipif(not hasattr(os, "nice"), reason="no process priorities on this platform")
@pytest.mark.parametrize(
    "nice",
    [None, pytest.param("0", marks=pytest.mark.slow), pytest.param("3", marks=pytest.mark.slow)],
)
def test_serve_runs_below_the_priority_it_was_started_with(tmp_path: Path, nice: str | None):
    """Planners sharing the machine come first (CPKB_SURROGATE__NICE, 5 unless set)."""
    env = {k: v for k, v in os.environ.items() if k != "CPKB_SURROGATE__NICE"}
    if nice is not None:
        env["CPKB_SURROGATE__NICE"] = nice
    port = free_port()
    command = [sys.executable, "-m", "cpkb", "serve", "--port", str(port)]
    command += ["--db", f"sqlite:///{tmp_path / 'kb.db'}"]
    server = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    try:
        assert wait_ready(f"http://127.0.0.1:{port}", server, timeout=START_TIMEOUT_S)
        below = os.getpriority(os.PRIO_PROCESS, server.pid) - os.getpriority(os.PRIO_PROCESS, 0)
    finally:
        stop_process(server)
    assert below == min(int(nice if nice is not None else 5), 19 - os.nice(0))


@pytest.mark.slow
def test_db_upgrade_defaults_to_cpkb_db_in_the_current_directory(tmp_path: Path) -> None:
    out = cpkb("db", "upgrade", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "cpkb.db").exists()


def _affinities(pid: int) -> list[set[int]]:
    """The cores each thread of process `pid` may run on."""
    return [os.sched_getaffinity(int(tid)) for tid in os.listdir(f"/proc/{pid}/task")]


@pytest.mark.slow
@pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs Linux CPU affinity and two cores",
)
def test_serve_runs_every_thread_on_the_cores_it_is_given(tmp_path: Path) -> None:
    last = max(os.sched_getaffinity(0))
    port = free_port()
    command = [sys.executable, "-m", "cpkb", "serve", "--port", str(port), "--cpu-cores", str(last)]
    command += ["--db", f"sqlite:///{tmp_path / 'kb.db'}"]
    server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    try:
        assert wait_ready(f"http://127.0.0.1:{port}", server, timeout=START_TIMEOUT_S)
        threads = _affinities(server.pid)
    finally:
        stop_process(server)
    assert len(threads) > 1 and all(cores == {last} for cores in threads)


def test_serve_with_a_bad_core_list_is_one_line_exit_2(tmp_path: Path) -> None:
    out = cpkb("serve", "--cpu-cores", "1-x", "--port", str(free_port()), cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert "bad setting cpu_cores" in out.stderr and "'1-x'" in out.stderr
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
    assert not (tmp_path / "cpkb.db").exists()


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs Linux CPU affinity")
def test_serve_on_cores_the_machine_lacks_is_one_line_exit_2(tmp_path: Path) -> None:
    missing = str(max(os.sched_getaffinity(0)) + 4096)
    out = cpkb("serve", "--cpu-cores", missing, "--port", str(free_port()), cwd=tmp_path)
    assert out.returncode == 2, out.stderr
    assert f"cannot run on cores {missing}" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "cpkb.db").exists()

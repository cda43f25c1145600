"""`cpkb plan` and `cpkb bench` against a knowledge base they cannot use: one line, exit 3.

A real token-protected `cpkb serve`, real subprocesses (a traceback only shows in one).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from service_support import LiveServer, run_live_server

from client import CpkbClient
from cpkb.cli import CliError
from cpkb.cli.reach import KB_UNAVAILABLE_STATUS, probe
from cpkb.embedded import free_port

TOKEN = "a-token-for-tests"
PLAN = ("plan", "--task", "analytic:desk", "--method", "cp-bo", "--quiet")
BENCH = ("bench", "--tasks", "analytic:desk", "--methods", "cp-bo", "--seeds", "1", "--quiet")


@pytest.fixture(scope="module")
def guarded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    """A service on a fresh SQLite file that wants TOKEN for every write."""
    tmp = tmp_path_factory.mktemp("guarded")
    with run_live_server(
        f"sqlite:///{tmp / 'kb.sqlite'}", tmp / "server.log", env={"CPKB_TOKEN": TOKEN}
    ) as server:
        yield server


def cpkb(*args: str, **env: str) -> subprocess.CompletedProcess[str]:
    """The command in a subprocess, without the caller's CPKB_TOKEN, plus `env`."""
    clean = {k: v for k, v in os.environ.items() if k != "CPKB_TOKEN"}
    return subprocess.run(
        [sys.executable, "-m", "cpkb", *args],
        capture_output=True,
        text=True,
        timeout=600,
        env={**clean, **env},
    )


def one_line_error(out: subprocess.CompletedProcess[str], command: str) -> str:
    """The error line, after checking it is the only output and the exit status is 3."""
    assert out.returncode == KB_UNAVAILABLE_STATUS, out.stderr[-3000:]
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr[-3000:]
    assert lines[0].startswith(f"cpkb {command}: error: ")
    return lines[0]


@pytest.mark.slow
def test_plan_without_a_token_is_told_to_pass_one(guarded: LiveServer) -> None:
    line = one_line_error(cpkb(*PLAN, "--kb-url", guarded.url), "plan")
    assert guarded.url in line and "401" in line
    assert "pass --token or set CPKB_TOKEN" in line


@pytest.mark.slow
def test_plan_with_a_wrong_token_is_told_to_check_it(guarded: LiveServer) -> None:
    line = one_line_error(cpkb(*PLAN, "--kb-url", guarded.url, "--token", "wrong"), "plan")
    assert "check --token or CPKB_TOKEN" in line


@pytest.mark.slow
def test_a_token_from_the_environment_is_the_one_probed(guarded: LiveServer) -> None:
    line = one_line_error(cpkb(*PLAN, "--kb-url", guarded.url, CPKB_TOKEN="wrong"), "plan")
    assert "check --token or CPKB_TOKEN" in line


@pytest.mark.slow
def test_the_probe_takes_the_right_token_and_creates_the_planners_knowledge_base(
    guarded: LiveServer,
) -> None:
    probe(guarded.url, TOKEN, kb="probed")
    probe(guarded.url, TOKEN, kb="probed")
    probe(guarded.url, TOKEN)
    with CpkbClient(guarded.url) as client:
        assert [kb.name for kb in client.list_kbs()].count("probed") == 1
    with pytest.raises(CliError, match="pass --token"):
        probe(guarded.url, None)


@pytest.mark.slow
def test_plan_against_a_url_that_is_not_the_service_names_the_answer(
    guarded: LiveServer,
) -> None:
    line = one_line_error(cpkb(*PLAN, "--kb-url", f"{guarded.url}/elsewhere"), "plan")
    assert "answered 404 GET /elsewhere/healthz" in line


@pytest.mark.slow
def test_plan_with_no_service_at_the_url_says_how_to_start_one() -> None:
    url = f"http://127.0.0.1:{free_port()}"
    line = one_line_error(cpkb(*PLAN, "--kb-url", url), "plan")
    assert f"cannot reach the knowledge base at {url}" in line and "cpkb serve" in line


@pytest.mark.slow
def test_plan_whose_embedded_service_cannot_start_is_one_line() -> None:
    out = cpkb(*PLAN, CPKB_DATABASE_URL="mysql://nobody@127.0.0.1/x")
    assert "embedded knowledge base did not start" in one_line_error(out, "plan")


@pytest.mark.slow
def test_bench_without_a_token_fails_before_any_run(guarded: LiveServer, tmp_path: Path) -> None:
    out_dir = tmp_path / "bench"
    line = one_line_error(cpkb(*BENCH, "--kb-url", guarded.url, "--out", str(out_dir)), "bench")
    assert "pass --token or set CPKB_TOKEN" in line
    assert not (out_dir / "runs.jsonl").exists()


@pytest.mark.slow
def test_bench_with_no_service_at_the_url_is_one_line(tmp_path: Path) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    out = cpkb(*BENCH, "--kb-url", url, "--out", str(tmp_path / "bench"))
    assert f"cannot reach the knowledge base at {url}" in one_line_error(out, "bench")


@pytest.mark.parametrize(
    ("command", "status_1"),
    [("plan", "1 when the budget ran out"), ("bench", "1 when runs failed")],
)
def test_help_documents_the_knowledge_base_exit_status(command: str, status_1: str) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "cpkb", command, "--help"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0
    text = " ".join(out.stdout.split())
    assert status_1 in text
    assert f"{KB_UNAVAILABLE_STATUS} when the knowledge base cannot be reached" in text


@pytest.mark.slow
@pytest.mark.parametrize("action", ["create", "delete"])
def test_kb_writes_refused_a_token_exit_3_as_plan_does(guarded: LiveServer, action: str) -> None:
    out = cpkb("kb", action, "x", "--kb-url", guarded.url, "--token", "wrong")
    assert "check --token or CPKB_TOKEN" in one_line_error(out, "kb")


@pytest.mark.slow
def test_demo_with_no_service_at_the_url_is_one_line() -> None:
    url = f"http://127.0.0.1:{free_port()}"
    out = cpkb("demo", "--analytic", "--seeds", "1", "--kb-url", url)
    assert f"cannot reach the knowledge base at {url}" in one_line_error(out, "demo")


@pytest.mark.slow
def test_plan_with_a_knowledge_base_that_does_not_exist_says_so(guarded: LiveServer) -> None:
    out = cpkb(*PLAN, "--kb-url", guarded.url, "--kb", "labb", "--token", TOKEN)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "knowledge base 'labb' does not exist" in lines[0]
    assert "--create-kb" in lines[0]
    with CpkbClient(guarded.url) as client:
        assert "labb" not in [kb.name for kb in client.list_kbs()]


@pytest.mark.slow
def test_plan_in_an_embedded_base_that_does_not_exist_says_so(tmp_path: Path) -> None:
    db = tmp_path / "kb.sqlite"
    out = cpkb(*PLAN, "--kb", "labb", CPKB_DATABASE_URL=f"sqlite:///{db}")
    assert out.returncode == 2, out.stderr
    assert "knowledge base 'labb' does not exist in the embedded" in out.stderr
    assert not db.exists()  # nothing was created


@pytest.mark.slow
def test_plan_with_create_kb_makes_the_base_and_runs(guarded: LiveServer) -> None:
    out = cpkb(
        *PLAN,
        "--kb-url",
        guarded.url,
        "--kb",
        "fresh",
        "--create-kb",
        "--token",
        TOKEN,
        "--max-rollouts",
        "5",
        "--json",
    )
    assert out.returncode in (0, 1), out.stderr
    with CpkbClient(guarded.url) as client:
        assert "fresh" in [kb.name for kb in client.list_kbs()]

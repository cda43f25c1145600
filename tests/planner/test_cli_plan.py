"""`cpkb plan` and `cpkb demo` from the command line: JSON as the last line, clear errors."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from cli_support import cpkb_in_process

from cpkb.cli import main


def test_plan_prints_the_result_as_its_last_json_line(capsys):
    code = main(
        ["plan", "--task", "analytic:desk", "--method", "quasi-random", "--seed", "2", "--json"]
    )
    out = capsys.readouterr().out.strip().splitlines()
    result = json.loads(out[-1])
    assert code == 0 and result["solved"] is True
    assert (result["task"], result["method"], result["seed"]) == ("desk", "quasi-random", 2)
    assert result["rollouts"] >= 1 and set(result["bindings"]) == {"#dir1", "#pose12"}
    assert result["kb"] is None and result["points_posted"] == 0


def test_plan_without_json_summarises_in_words(capsys):
    code = main(["plan", "--task", "analytic:desk", "--method", "quasi-random", "--quiet"])
    assert code == 0
    assert "solved after" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--task", "no-such-task", "--method", "quasi-random"], "no-such-task"),
        (["--task", "analytic:desk", "--method", "simulated-annealing"], "unknown method"),
        (
            ["--task", "analytic:desk", "--method", "quasi-random", "--max-rollouts", "0"],
            "--max-rollouts",
        ),
    ],
)
def test_plan_mistakes_are_one_line_errors(argv, message, capfd):
    out = cpkb_in_process(capfd, "plan", *argv, "--json")
    assert out.returncode == 2, out.stderr
    assert message in out.stderr and "Traceback" not in out.stderr


def test_a_misspelled_task_fails_before_any_progress_is_drawn(capfd):
    out = cpkb_in_process(capfd, "plan", "--task", "deks", "--method", "quasi-random")
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [
        "cpkb plan: error: deks: no such task (shipped: deskP, desk, regrasp, packP1, packP2, "
        "packP3, pack; or give a .yaml file)"
    ]


@pytest.mark.parametrize(
    ("url", "message"),
    [
        (
            "127.0.0.1:8000",
            "is not an http:// or https:// URL (did you mean http://127.0.0.1:8000?)",
        ),
        ("ftp://127.0.0.1:8000", "is not an http:// or https:// URL"),
        ("http://", "is not an http:// or https:// URL"),
    ],
)
def test_a_kb_url_that_is_not_an_http_url_is_a_usage_error(url, message, capfd):
    out = cpkb_in_process(capfd, "plan", "--task", "analytic:desk", "--kb-url", url)
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [f"cpkb plan: error: --kb-url {url!r} {message}"]


def test_a_bad_knowledge_base_name_is_a_usage_error(capsys):
    code = main(["plan", "--task", "analytic:desk", "--kb", "no spaces", "--quiet"])
    assert code == 2
    assert "bad knowledge base name 'no spaces'" in capsys.readouterr().err


def test_demo_runs_on_the_analytic_worlds(kb_service, capsys):
    code = main(["demo", "--analytic", "--seeds", "1", "--kb-url", kb_service])
    out = capsys.readouterr().out
    assert code == 0
    assert re.search(r"rollouts on average,\s+quasi-random-restarts", out)
    assert "Where to look next" in out
    assert re.search(r"\d+%\s+(fewer|more)\s+with\s+knowledge", out)


@pytest.mark.slow
def test_plan_desk_with_cp_bo_end_to_end(tmp_path: Path):
    """The real PyBullet desk, an embedded knowledge base on its own SQLite file."""
    env = {**os.environ, "CPKB_DATABASE_URL": f"sqlite:///{tmp_path / 'kb.db'}"}
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "cpkb",
            "plan",
            "--task",
            "desk",
            "--method",
            "cp-bo",
            "--seed",
            "0",
            "--json",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["solved"] and result["task"] == "desk" and result["method"] == "cp-bo"
    assert result["points_posted"] >= result["rollouts"] - 1 and result["types_active"] >= 1
    assert result["wall_s"] >= result["sim_s"] > 0 and result["kb_s"] > 0


def test_plan_names_every_method_the_planner_knows() -> None:
    from cpkb.cli.planning import METHODS
    from planner.search import samplers

    assert sorted(METHODS) == samplers.methods()


def test_the_demo_names_cpkb_as_this_shell_can_run_it(monkeypatch, tmp_path):
    from planner.demo import _command

    program = tmp_path / ".venv" / "bin" / "cpkb"
    program.parent.mkdir(parents=True)
    program.write_text("")
    program.chmod(0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", [str(program), "demo"])
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    assert _command() == ".venv/bin/cpkb"
    monkeypatch.setenv("PATH", f"{program.parent}:/usr/bin:/bin")
    assert _command() == "cpkb"

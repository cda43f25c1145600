"""The root command answers --help and rejects unknown subcommands without a traceback."""

import subprocess
import sys


def test_help_lists_the_command() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "cpkb", "--help"], capture_output=True, text=True, check=True
    )
    assert "usage: cpkb" in out.stdout


def test_unknown_subcommand_is_a_clear_error() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "cpkb", "no-such-command"], capture_output=True, text=True
    )
    assert out.returncode == 2
    assert "invalid choice" in out.stderr
    assert "Traceback" not in out.stderr


def test_version_is_the_installed_distributions() -> None:
    from importlib.metadata import version

    out = subprocess.run(
        [sys.executable, "-m", "cpkb", "--version"], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == f"cpkb {version('cpkb')}"


def test_help_speaks_to_users() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "cpkb", "--help"], capture_output=True, text=True, check=True
    )
    assert "cpkb demo" in out.stdout and "registered" not in out.stdout

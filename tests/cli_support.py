"""A cpkb command run by `main` in the test's process, for the checks that need no
interpreter of their own (argument errors, client commands against a real server)."""

from __future__ import annotations

import subprocess

import pytest

from cpkb.cli import main


def cpkb_in_process(
    capfd: pytest.CaptureFixture[str], *args: str
) -> subprocess.CompletedProcess[str]:
    """Exit status and output as a subprocess would give them (argparse's usage errors
    included)."""
    capfd.readouterr()
    try:
        code = main(list(args))
    except SystemExit as exc:
        code = exc.code
    out = capfd.readouterr()
    return subprocess.CompletedProcess(["cpkb", *args], code, out.out, out.err)

"""The `cpkb` command: one entry point, subcommands registered by small modules.

Each module in `COMMAND_MODULES` exposes `register(subparsers)`; modules keep heavy imports
inside their handlers so that `cpkb --help` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

COMMAND_MODULES = (
    "cpkb.cli.service",
    "cpkb.cli.world",
    "cpkb.cli.planning",
    "cpkb.cli.bench",
    "cpkb.cli.generate",
)


class CliError(Exception):
    """A user mistake: printed as one line on stderr, exit status 2 (subclasses may differ)."""

    exit_status = 2


USAGE = """\
cpkb learns where a workspace's geometric constraints lie from every failed binding search
(CP-BO: Ren et al., Learning Geometric Constraints in Task and Motion Planning) and uses that
knowledge to guide the next search, in any task of the same workspace.

Start with `cpkb demo`; `cpkb plan` runs one search, `cpkb serve` a knowledge base that many
planners share, `cpkb bench` the paper's evaluation. `cpkb COMMAND --help` explains each.
"""


def build_parser() -> argparse.ArgumentParser:
    from importlib.metadata import version

    parser = argparse.ArgumentParser(
        prog="cpkb", description=USAGE, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"cpkb {version('cpkb')}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        module.register(sub)
    return parser


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    # A SIGTERM (a scheduler's stop, `kill`) unwinds like Ctrl-C, so that an embedded service
    # and a bench's worker pool are stopped rather than left running (`cpkb serve`'s uvicorn
    # installs its own handlers).
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        return int(args.handler(args) or 0)
    except CliError as exc:
        print(f"cpkb {args.command}: error: {exc}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        return 130

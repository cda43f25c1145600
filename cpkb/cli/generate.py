"""`cpkb generate`: a suite of random tabletop workspaces with desk-, regrasp- and pack-like
targets and their predecessors, each target checked solvable by quasi-random."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cpkb.cli import CliError
from cpkb.cli.argtypes import positive_int


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "generate",
        help="write a suite of random workspaces and tasks (with predecessors) to a directory",
        description=(
            "Write N random tabletop workspaces under OUT (ws00, ws01, ...), each with a "
            "desk-like, a regrasp-like and a pack-like target (role: target) and their "
            "predecessors, and OUT/suite.yaml, the index. Each target is probed with "
            "quasi-random: solved within --probe-rollouts on most of --probe-seeds seeds and "
            "needing more than 3 rollouts in the median, or it is redrawn. Everything is drawn "
            "from --seed. Run the suite with `cpkb bench --tasks OUT`."
        ),
    )
    parser.add_argument("--out", type=Path, required=True, help="the suite's directory")
    parser.add_argument("--workspaces", type=positive_int, default=4, help="how many (default 4)")
    parser.add_argument("--seed", type=int, default=0, help="the suite's seed (default 0)")
    parser.add_argument(
        "--probe-seeds",
        type=positive_int,
        default=3,
        help="quasi-random runs per target (default 3)",
    )
    parser.add_argument(
        "--probe-rollouts", type=positive_int, default=500, help="each probe's budget (default 500)"
    )
    parser.add_argument(
        "--no-check", action="store_true", help="skip the probes (the layouts are unchecked)"
    )
    parser.add_argument("--quiet", action="store_true", help="no line per probe")
    parser.set_defaults(handler=handle)


def handle(args: argparse.Namespace) -> int:
    from planner.tasks.generator import GenerationError, ProbeSettings, generate_suite

    if args.out.exists() and not args.out.is_dir():
        raise CliError(f"--out {args.out} exists and is not a directory")
    settings = ProbeSettings(
        seeds=args.probe_seeds, max_rollouts=args.probe_rollouts, check=not args.no_check
    )
    log = (lambda _: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    try:
        made = generate_suite(args.out, args.workspaces, args.seed, settings, log)
    except GenerationError as exc:
        raise CliError(str(exc)) from None
    print(
        f"wrote {len(made['targets'])} targets in {args.workspaces} workspaces to {args.out} "
        f"in {made['wall_s']:.0f} s (index: {args.out / 'suite.yaml'})"
    )
    return 0

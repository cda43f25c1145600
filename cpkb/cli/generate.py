"""`cpkb generate`: a suite of random tabletop workspaces with desk-, regrasp- and pack-like
targets and their predecessors, each target checked solvable by quasi-random; with `--difficulty
hard`, the hard family's targets, each checked solvable and hard."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
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
            "from --seed. Run the suite with `cpkb bench --tasks OUT`. With --difficulty hard, "
            "each workspace holds a tight packing (5 to 8 boxes of mixed sizes covering 45 % "
            "or more of a tray's usable area) instead, kept only when a binding is found for it "
            "(played in the simulator, recorded in suite.yaml) and quasi-random-restarts' "
            "median over the probes is at least 500 rollouts, an unsolved probe counting as "
            "more than any, one probe at least solving it."
        ),
    )
    parser.add_argument("--out", type=Path, required=True, help="the suite's directory")
    parser.add_argument("--workspaces", type=positive_int, default=4, help="how many (default 4)")
    parser.add_argument("--seed", type=int, default=0, help="the suite's seed (default 0)")
    parser.add_argument(
        "--difficulty",
        choices=("standard", "hard"),
        default="standard",
        help="standard (desk, regrasp, pack) or the hard family (default standard)",
    )
    parser.add_argument(
        "--probe-seeds",
        type=positive_int,
        default=3,
        help="quasi-random runs per target (default 3)",
    )
    parser.add_argument(
        "--probe-rollouts",
        type=positive_int,
        default=None,
        help="each probe's budget (default 500; 2000 with --difficulty hard)",
    )
    parser.add_argument(
        "--no-check", action="store_true", help="skip the probes (the layouts are unchecked)"
    )
    parser.add_argument("--quiet", action="store_true", help="no line per probe")
    parser.set_defaults(handler=handle)


def handle(args: argparse.Namespace) -> int:
    from planner.tasks.generator import (
        GenerationError,
        HardProbe,
        ProbeSettings,
        generate_hard_suite,
        generate_suite,
    )

    if args.out.exists() and not args.out.is_dir():
        raise CliError(f"--out {args.out} exists and is not a directory")
    log = (lambda _: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    try:
        if args.difficulty == "hard":
            hard = HardProbe(seeds=args.probe_seeds, check=not args.no_check)
            if args.probe_rollouts is not None:
                hard = replace(hard, max_rollouts=args.probe_rollouts)
            made = generate_hard_suite(args.out, args.workspaces, args.seed, hard, log)
        else:
            settings = ProbeSettings(
                seeds=args.probe_seeds,
                max_rollouts=args.probe_rollouts or ProbeSettings.max_rollouts,
                check=not args.no_check,
            )
            made = generate_suite(args.out, args.workspaces, args.seed, settings, log)
    except GenerationError as exc:
        raise CliError(str(exc)) from None
    print(
        f"wrote {len(made['targets'])} targets in {args.workspaces} workspaces to {args.out} "
        f"in {made['wall_s']:.0f} s (index: {args.out / 'suite.yaml'})"
    )
    return 0

"""`cpkb bench`: the paper's experiment, tasks x methods x seeds on a pool of workers."""

from __future__ import annotations

import argparse
import os
from typing import Any

from cpkb.cli import CliError
from cpkb.cli.argtypes import non_negative_int, parse_duration, positive_int
from cpkb.cli.config_args import add_config_arguments, config_overrides
from cpkb.cli.reach import EXIT_STATUS_HELP, probe

DEFAULT_TASKS = "desk,regrasp,pack"
DEFAULT_METHODS = "quasi-random,quasi-random-restarts,mcts-bo,cp-bo,cp-bo-transfer,optuna-tpe"


def _csv_list(text: str) -> list[str]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError("give at least one name, comma-separated")
    if len(set(items)) != len(items):
        raise argparse.ArgumentTypeError(f"a name is repeated in {text!r}")
    return items


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "bench",
        help="the paper's evaluation: rollouts to the first feasible binding per method",
        description=(
            "Run tasks x methods x seeds, each scenario in a fresh knowledge base, on a pool of "
            "worker processes. Results are appended run by run to OUT/runs.jsonl; a rerun with "
            "the same --out skips finished runs. Writes OUT/summary.md, OUT/summary.csv and "
            "the plots OUT/rollouts.* and OUT/wall_time.* (PNG, SVG, PDF). The defaults run "
            "3 tasks x 6 methods x 100 seeds = 1,800 runs (days on a laptop): try --seeds 3 "
            "first."
        ),
        epilog="Exit status: 0 when every asked run has a result, 1 when runs failed or were "
        f"left (time limit, interrupt), 2 for a usage error, {EXIT_STATUS_HELP}.",
    )
    parser.add_argument(
        "--tasks",
        type=_csv_list,
        default=_csv_list(DEFAULT_TASKS),
        help="shipped names, task files, or suite directories (a directory stands for its "
        f"target task files, e.g. one written by `cpkb generate`); default {DEFAULT_TASKS}",
    )
    parser.add_argument(
        "--methods",
        type=_csv_list,
        default=_csv_list(DEFAULT_METHODS),
        help="samplers, plus quasi-random-restarts (quasi-random with cp-bo's restarts and "
        "redraws: the strongest baseline, which the summaries measure against), "
        "cp-bo-transfer (cp-bo after the task's predecessors, "
        "30 rollouts each, in the same knowledge base), cp-bo-paper (the paper's CP-BO: "
        "cp-bo with every extension off) and cp-bo-paper-transfer (the paper's CP-BO "
        f"Transfer); default {DEFAULT_METHODS}",
    )
    parser.add_argument(
        "--seeds",
        type=positive_int,
        default=100,
        help="seeds per (task, method) cell: runs = tasks x methods x seeds; default 100",
    )
    parser.add_argument(
        "--first-seed",
        type=non_negative_int,
        default=0,
        help="the first seed; a cell runs seeds FIRST..FIRST+SEEDS-1 (default 0), so another "
        "block of seeds adds to the same --out",
    )
    parser.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        help="worker processes (default: the machine's cores; 1 with --cores)",
    )
    parser.add_argument(
        "--cores",
        type=positive_int,
        default=None,
        metavar="N",
        help="every method gets N cores in all, one run at a time (pinned; Linux): a guided "
        "method's planner one and its embedded service the others (with N=1, the planner's "
        "own), a method without knowledge N trees at once, the first binding winning and "
        "the rollouts summed over the trees; recorded with the results; default: cores are "
        "not counted",
    )
    parser.add_argument(
        "--concurrent",
        type=positive_int,
        default=1,
        metavar="N",
        help="plan the runs of a cell N at a time on one fresh knowledge base (seeds "
        "first..first+N-1 share one, the next N the next; at least N workers); each run's "
        "record names its group; default 1: each run alone. The same seeds are run alone "
        "too (into --alone), and OUT/summary_concurrent.md compares the two, with the "
        "points each group's base holds against those its runs posted",
    )
    parser.add_argument(
        "--mixed",
        action="store_true",
        help="with --concurrent N: a group is N runs of different tasks of one workspace "
        "(the tasks in turn, seed by seed: --tasks desk,regrasp,pack --concurrent 3 runs "
        "each seed's three tasks at once), as a lab's planners share one knowledge base",
    )
    parser.add_argument(
        "--alone",
        metavar="DIR",
        default=None,
        help="with --concurrent N: the results directory of the same seeds run alone (its "
        "missing runs are run first; share it between benches of several N; one that holds "
        "them all is only read, whatever knobs it was run with); default OUT/alone",
    )
    parser.add_argument("--out", default="bench-out", help="results directory (resumable)")
    parser.add_argument(
        "--kb-url",
        default=None,
        help="a running cpkb service to share (replicas as URL1,URL2); default: one embedded "
        "service for the whole bench on a temporary SQLite file (a fresh knowledge base per "
        "scenario either way)",
    )
    parser.add_argument(
        "--service-cores",
        choices=("spare", "shared"),
        default="spare",
        help="where the embedded service and its fits run: on the cores the workers leave "
        "(spare, default; Linux, where --workers leaves any), so that no planner waits for "
        "a fit, or on any core at a lower priority (shared, as benches before it ran); "
        "recorded with the results",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="run the scenarios as tasks on the running Ray cluster at ADDRESS (the head's "
        "host:port, or auto); the cluster's CPUs, not --workers, set how many run at once; "
        "without --kb-url each Ray worker process embeds its own service (needs the ray extra)",
    )
    parser.add_argument("--token", default=None, help="access token (default: CPKB_TOKEN)")
    parser.add_argument(
        "--suggest-in",
        choices=("planner", "service"),
        default="planner",
        help="where cp-bo maximises MPF: in each planner from the service's model snapshots "
        "(default), or in the service",
    )
    parser.add_argument(
        "--max-rollouts",
        type=positive_int,
        default=2000,
        help="rollout budget of a run; an unsolved run counts as this many (default 2000)",
    )
    parser.add_argument(
        "--time-budget",
        type=parse_duration,
        default=None,
        metavar="SECONDS",
        help="a target run's budget in wall-clock time as well (60, 90s, 2m; predecessors "
        "keep their rollouts): no rollout starts after it; the summary counts a run solved "
        "only within it, and an unsolved run's time as the budget",
    )
    parser.add_argument(
        "--predecessor-rollouts",
        type=positive_int,
        default=30,
        help="rollouts spent on each predecessor task before the target in the transfer "
        "methods (the whole budget, filling the knowledge base; default 30)",
    )
    parser.add_argument(
        "--time-limit",
        type=parse_duration,
        default=None,
        help="stop after this long (600, 30m, 2h); runs in flight are redone by a rerun",
    )
    parser.add_argument(
        "--summary-only", action="store_true", help="only rebuild the table and plots from OUT"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument(
        "--variants",
        metavar="FILE",
        help="named variants of the methods, each a method with planner knobs "
        "(`variants: {NAME: {method: cp-bo, set: {cp_bo.lookahead: false}}}`, YAML or JSON), "
        "usable in --methods; benchmarks/ablation.yaml turns off each extension of cp-bo in turn",
    )
    add_config_arguments(parser)
    parser.set_defaults(handler=handle)


def suite_tasks(tasks: list[str]) -> list[str]:
    """`--tasks` with each directory replaced by its suite's target task files."""
    from pathlib import Path

    from planner.tasks import TaskError
    from planner.tasks.suites import suite_targets

    expanded: list[str] = []
    for task in tasks:
        if not os.path.isdir(task):
            expanded.append(task)
            continue
        try:
            expanded += [str(p) for p in suite_targets(Path(task))]
        except TaskError as exc:
            raise CliError(str(exc)) from None
    return expanded


def bench_variants(path: str | None) -> dict[str, Any]:
    """The variants file's variants, checked; a mistake is a CLI error naming it."""
    if path is None:
        return {}
    from cpkb.bench.app import known_methods
    from cpkb.bench.variants import load_variants
    from planner.config import ConfigError

    try:
        return load_variants(path, known_methods())
    except ConfigError as exc:
        raise CliError(str(exc)) from None


def handle(args: argparse.Namespace) -> int:
    from cpkb.bench.app import BenchSettings, check_request, run_command
    from server.settings import Settings

    configured = Settings().token
    token = args.token or (configured.get_secret_value() if configured is not None else None)

    settings = BenchSettings(
        tasks=suite_tasks(args.tasks),
        methods=args.methods,
        seeds=range(args.first_seed, args.first_seed + args.seeds),
        workers=args.workers or (1 if args.cores else os.cpu_count() or 1),
        out_dir=args.out,
        kb_url=args.kb_url,
        token=token,
        suggest_in=args.suggest_in,
        max_rollouts=args.max_rollouts,
        time_budget_s=args.time_budget,
        predecessor_rollouts=args.predecessor_rollouts,
        time_limit_s=args.time_limit,
        summary_only=args.summary_only,
        quiet=args.quiet,
        config=config_overrides(args),
        concurrent=args.concurrent,
        mixed=args.mixed,
        alone_dir=args.alone,
        variants=bench_variants(args.variants),
        ray_address=args.ray,
        service_cores=args.service_cores,
        cores=args.cores,
    )
    try:
        if args.kb_url is not None and not args.summary_only:
            check_request(settings)
            probe(args.kb_url, token)
        return run_command(settings)
    except ValueError as exc:
        raise CliError(str(exc)) from None

"""`cpkb plan` (one binding search) and `cpkb demo` (the README's main job)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from cpkb.cli import CliError
from cpkb.cli.argtypes import parse_duration
from cpkb.cli.config_args import add_config_arguments, plan_config
from cpkb.cli.reach import (
    EXIT_STATUS_HELP,
    checked_kb_name,
    checked_url,
    explained,
    probe,
    require_kb,
)

METHODS = ("quasi-random", "quasi-random-restarts", "mcts-bo", "cp-bo", "cp-bo-paper", "optuna-tpe")


def register(subparsers: Any) -> None:
    plan = subparsers.add_parser(
        "plan",
        help="search bindings for one task",
        description="Search for a feasible binding list of one task (grasps, placements, "
        "motions) with PW-UCT and the chosen sampler, and print what it took. The knowledge-"
        "base methods (cp-bo, cp-bo-paper) post every failure to the knowledge base and use "
        "what earlier runs learned; without --kb-url an embedded service on ./cpkb.db is used.",
        epilog="Example: cpkb plan --task desk --method cp-bo --seed 0. "
        "Exit status: 0 when a feasible binding list was found, 1 when the budget ran "
        f"out, 2 for a usage error, {EXIT_STATUS_HELP}.",
    )
    plan.add_argument("--task", required=True, help="a task name (see `cpkb tasks`) or task file")
    plan.add_argument("--method", default="cp-bo", help=f"{' | '.join(METHODS)} (default cp-bo)")
    plan.add_argument("--seed", type=int, default=0, help="the run's seed (default 0)")
    plan.add_argument("--max-rollouts", type=int, default=2000, help="rollout budget (2000)")
    plan.add_argument(
        "--time-budget",
        type=parse_duration,
        default=None,
        metavar="SECONDS",
        help="a budget in wall-clock time as well (60, 90s, 2m): no rollout starts after it, "
        "counted from loading the world; whichever budget ends first stops the run",
    )
    plan.add_argument(
        "--full-budget",
        action="store_true",
        help="spend the whole --max-rollouts budget instead of stopping at the first feasible "
        "binding list: every failure met is posted, so a predecessor task fills the knowledge "
        "base for a later task (what cp-bo-transfer does with 30 rollouts per predecessor; "
        "`cpkb types` shows when the fits have landed)",
    )
    plan.add_argument(
        "--kb-url",
        help="knowledge-base service URL, or its replicas' as URL1,URL2 (the client fails over); "
        "default: an embedded one",
    )
    plan.add_argument(
        "--kb",
        default="default",
        help="knowledge base name (default: default); any other must exist, or pass --create-kb",
    )
    plan.add_argument(
        "--create-kb",
        action="store_true",
        help="create the --kb knowledge base if it does not exist (else a name that does not "
        "exist is an error: a misspelt one would learn from nothing)",
    )
    plan.add_argument("--token", help="access token (default: CPKB_TOKEN)")
    plan.add_argument(
        "--suggest-in",
        choices=("planner", "service"),
        default="planner",
        help="where cp-bo maximises MPF: here, from the service's model snapshots (default), "
        "or in the service (which also pushes planners sharing a knowledge base apart)",
    )
    plan.add_argument("--gui", action="store_true", help="show the PyBullet GUI")
    plan.add_argument("--json", action="store_true", help="print the result as JSON (last line)")
    plan.add_argument("--quiet", action="store_true", help="no progress display")
    add_config_arguments(plan)
    plan.set_defaults(handler=_plan)

    demo = subparsers.add_parser(
        "demo",
        help="deskP then desk with cp-bo on one knowledge base, beside quasi-random",
        description="The paper's transfer on one machine: quasi-random on desk, then cp-bo "
        "learning on deskP and solving desk with what it learned, --seeds times each, and a "
        "table of rollouts to the first feasible binding. Ends with where to look next.",
    )
    demo.add_argument("--seeds", type=int, default=3, help="seeds per method (default 3)")
    demo.add_argument("--predecessor-rollouts", type=int, default=30, help="deskP budget (30)")
    demo.add_argument("--db", metavar="URL", help="database URL (default: the embedded default)")
    demo.add_argument(
        "--kb-url", help="use this running service (URL, or replicas as URL1,URL2) instead"
    )
    demo.add_argument(
        "--analytic",
        action="store_true",
        help="use the simulator-free analytic desk and deskP (a seconds-long dry run)",
    )
    demo.set_defaults(handler=_demo)


def _run(args: argparse.Namespace, **kwargs: Any) -> Any:
    """`run_plan` with user mistakes and knowledge-base failures turned into CLI errors."""
    import httpx

    from client import CpkbError
    from cpkb.embedded import EmbeddedServiceError, service_url
    from planner.run import run_plan
    from planner.search import samplers

    try:
        if kwargs["kb_url"] is not None or not samplers.uses_knowledge(kwargs["method"]):
            return run_plan(**kwargs)
        with service_url(None) as url:
            return run_plan(**{**kwargs, "kb_url": url})
    except (CpkbError, EmbeddedServiceError, httpx.HTTPError) as exc:
        raise explained(exc, args.kb_url or "the embedded service", kwargs["token"]) from None
    except (ValueError, KeyError, FileNotFoundError) as exc:
        raise CliError(str(exc).strip("'\"")) from exc


def _check_task(task: str) -> None:
    """Load the task's description (not its world), so a misspelled name fails at once."""
    from planner.run import ANALYTIC_PREFIX

    try:
        if task.startswith(ANALYTIC_PREFIX):
            from planner.search.analytic import analytic_world

            analytic_world(task.removeprefix(ANALYTIC_PREFIX))
        else:
            from planner.tasks import load_task

            load_task(task)
    except ValueError as exc:
        raise CliError(str(exc)) from None


def _check_knowledge(args: argparse.Namespace, token: str | None) -> None:
    """Probe a given service before the search starts, when the method uses one."""
    from planner.search import samplers

    checked_kb_name(args.kb)
    if args.method not in samplers.methods() or not samplers.uses_knowledge(args.method):
        return
    if args.kb_url is not None:
        checked_url(args.kb_url)
        probe(args.kb_url, token, kb=args.kb if args.create_kb else None)
    if not args.create_kb:
        require_kb(args.kb, args.kb_url, token)


def _configured_token() -> str | None:
    """CPKB_TOKEN, read by the one settings module."""
    from server.settings import Settings

    configured = Settings().token
    return configured.get_secret_value() if configured is not None else None


def _plan(args: argparse.Namespace) -> int:
    if args.max_rollouts < 1:
        raise CliError("--max-rollouts must be at least 1")
    config = plan_config(args)
    token = args.token or _configured_token()
    _check_task(args.task)
    _check_knowledge(args, token)
    options = dict(
        task=args.task,
        method=args.method,
        seed=args.seed,
        max_rollouts=args.max_rollouts,
        time_budget_s=args.time_budget,
        kb_url=args.kb_url,
        kb=args.kb,
        token=token,
        stop_at_first=not args.full_budget,
        gui=args.gui,
        suggest_in=args.suggest_in,
        config=config,
    )
    result = _run(args, quiet=args.json or args.quiet, **options)
    if args.json:
        print(json.dumps(result.to_json()))
    else:
        _summary(result)
    return 0 if result.solved else 1


def _summary(result: Any) -> None:
    from rich.console import Console

    console = Console()
    verdict = "[green]solved[/]" if result.solved else "[red]not solved[/]"
    console.print(
        f"{result.task} with {result.method} (seed {result.seed}): {verdict} after "
        f"[bold]{result.rollouts}[/] rollouts in {result.wall_s:.2f} s "
        f"(simulation {result.sim_s:.2f} s, knowledge base {result.knowledge.kb_s:.2f} s)"
    )
    if result.kb is not None:
        stats = result.knowledge
        console.print(
            f"knowledge base '{result.kb}': {stats.types_activated} types activated from earlier "
            f"runs with {stats.points_activated} points; {stats.types_active} types active; "
            f"{stats.points_posted} points posted; {stats.suggestions} suggestions"
        )
    if result.bindings:
        # Plain print: rich wraps at 80 columns when piped, and this line is pasted whole into
        # `cpkb render --binding`.
        print("bindings: " + json.dumps(result.bindings), flush=True)


def _demo(args: argparse.Namespace) -> int:
    import httpx

    from client import CpkbError
    from cpkb.embedded import EmbeddedServiceError, service_url
    from planner.demo import run_demo

    if args.seeds < 1 or args.predecessor_rollouts < 1:
        raise CliError("--seeds and --predecessor-rollouts must be at least 1")
    token = _configured_token()
    if args.kb_url is not None:
        probe(checked_url(args.kb_url), token)
    try:
        with service_url(args.kb_url, args.db) as url:
            return run_demo(
                url,
                seeds=args.seeds,
                predecessor_rollouts=args.predecessor_rollouts,
                prefix="analytic:" if args.analytic else "",
                embedded=args.kb_url is None,
                db=args.db,
            )
    except (CpkbError, EmbeddedServiceError, httpx.HTTPError) as exc:
        raise explained(exc, args.kb_url or "the embedded service", token) from None

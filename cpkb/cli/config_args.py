"""`--set KEY=VALUE` and `--config FILE`: any knob of `planner.config.PlanConfig` from the command
line, so that a variant of the planner is a command, not a commit."""

from __future__ import annotations

import argparse
from typing import Any

from cpkb.cli import CliError


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        dest="config_set",
        help="set one planner knob, e.g. cp_bo.lookahead=false or search.pw_k=10 (repeatable; "
        "applied after --config)",
    )
    parser.add_argument(
        "--deterministic",
        action="store_true",
        help="wait for each refit the planner's points ask for, so that a seed gives the same "
        "rollouts on a fresh knowledge base (slower; knowledge.deterministic=true)",
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        dest="config_file",
        help="planner knobs from a YAML or JSON file (nested sections or dotted keys; a run's "
        "recorded `config` works)",
    )


def config_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The dotted overrides of `--config` then `--set`, checked against the known keys and
    their types; a mistake is a CLI error naming the key."""
    from planner.config import (
        ConfigError,
        PlanConfig,
        load_file,
        parse_assignments,
        typed_overrides,
    )

    try:
        overrides = load_file(args.config_file) if args.config_file else {}
        overrides.update(parse_assignments(args.config_set))
        if args.deterministic:
            overrides["knowledge.deterministic"] = True
        PlanConfig().with_overrides(overrides)  # the values' ranges, checked now
        return typed_overrides(overrides)
    except ConfigError as exc:
        raise CliError(str(exc)) from None


def plan_config(args: argparse.Namespace) -> Any:
    """The `PlanConfig` that `--config` and `--set` describe."""
    from planner.config import PlanConfig

    return PlanConfig().with_overrides(config_overrides(args))

"""A run function's result as a bench record (shared by the runner and a portfolio's trees)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

REQUIRED_FIELDS = ("solved", "rollouts", "wall_s")


class JsonResult(Protocol):
    """A result that writes itself as a record (`planner.result.PlanResult`)."""

    def to_json(self) -> Mapping[str, Any]: ...


# What a run function returns: a PlanResult, or a record already (a portfolio, a test's planner).
RunResult = JsonResult | Mapping[str, Any]


def as_record(result: RunResult) -> dict[str, Any]:
    """A run function's result as a record, checked for the fields every run has."""
    out = dict(result) if isinstance(result, Mapping) else dict(result.to_json())
    missing = [k for k in REQUIRED_FIELDS if k not in out]
    if missing:
        raise ValueError(f"the run result lacks {', '.join(missing)}")
    return out

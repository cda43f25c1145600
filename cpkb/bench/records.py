"""A run function's result as a bench record (shared by the runner and a portfolio's trees)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

REQUIRED_FIELDS = ("solved", "rollouts", "wall_s")


def as_record(result: Any) -> dict[str, Any]:
    """A run function's result as a record, checked for the fields every run has."""
    if hasattr(result, "to_json"):
        result = result.to_json()
    if isinstance(result, str | bytes):
        result = json.loads(result)
    if not isinstance(result, Mapping):
        raise TypeError(f"the run function returned {type(result).__name__}, not a result")
    out = dict(result)
    missing = [k for k in REQUIRED_FIELDS if k not in out]
    if missing:
        raise ValueError(f"the run result lacks {', '.join(missing)}")
    return out

"""The types of a recorded desk cp-bo run (`tests/surrogate/fixtures/suggest_requests.json`, see
its `record_suggest_requests.py`) held in memory as the service holds them, fitted once per test
session: a fit costs a test far more than the reads it is there for."""

from __future__ import annotations

import copy
import functools
import json
from pathlib import Path
from typing import Any

from surrogate.domains import space_from_json
from surrogate.sources import InMemoryModels

RECORDED: dict[str, Any] = json.loads(
    (Path(__file__).parent / "surrogate" / "fixtures" / "suggest_requests.json").read_text()
)


@functools.cache
def _fitted() -> InMemoryModels:
    memory = InMemoryModels()
    for recorded in RECORDED["types"]:
        nodes = recorded["graph"]["nodes"]
        space = {n["label"]: n["domain"] for n in nodes if n["role"] == "decision"}
        points = [(p["x"], p["feasible"]) for p in recorded["points"]]
        memory.add(recorded["type_id"], space_from_json(space), points)
        memory.model(recorded["type_id"])
    return memory


def recorded_models() -> InMemoryModels:
    """The recorded types with their points and fits: a copy of its own, which a test may add
    to."""
    return copy.deepcopy(_fitted())

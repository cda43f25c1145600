"""A tiny analytic planner with `run_plan`'s signature, to drive the bench harness in tests.

It binds one variable x in [0, 1] whose feasible set is [0.9, 1]: each rollout draws x
(uniformly for `quasi-random`; from [0.5, 1] for the other methods, so they need fewer
rollouts, as a guided sampler would), after sleeping `sleep_s` (only on `sleep_seeds` if
given). The task `never` has no feasible x. Every call is logged to `log_path` (one JSON
line), so tests can see which runs were executed, in which order, with which arguments; each
rollout is reported to `progress`, as `run_plan` does.
"""

from __future__ import annotations

import json
import os
import time
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class ToyProgress:
    rollouts: int


def toy_run(
    task: str,
    method: str,
    seed: int,
    *,
    max_rollouts: int,
    kb_url: str | None,
    kb: str | None,
    quiet: bool,
    log_path: str,
    sleep_s: float = 0.0,
    sleep_seeds: Iterable[int] | None = None,
    fail_seeds: tuple[int, ...] = (),
    stop_at_first: bool = True,
    progress: Callable[[ToyProgress], None] | None = None,
) -> dict[str, object]:
    started = time.perf_counter()
    with Path(log_path).open("a", encoding="utf-8") as handle:
        call = {
            "task": task,
            "method": method,
            "seed": seed,
            "kb": kb,
            "kb_url": kb_url,
            "max_rollouts": max_rollouts,
            "stop_at_first": stop_at_first,
            "pid": os.getpid(),
            "cpus": sorted(os.sched_getaffinity(0)),
        }
        handle.write(json.dumps(call) + "\n")
    if seed in fail_seeds:
        raise RuntimeError(f"toy failure on seed {seed}")
    if sleep_seeds is None or seed in sleep_seeds:
        time.sleep(sleep_s)
    rng = np.random.default_rng([seed, zlib.crc32(f"{task}/{method}".encode())])
    low = 0.0 if method == "quasi-random" else 0.5
    rollouts, solved = 0, False
    while rollouts < max_rollouts:
        rollouts += 1
        if progress is not None:
            progress(ToyProgress(rollouts))
        if rng.uniform(low, 1.0) >= 0.9 and task != "never":
            solved = True
            if stop_at_first:
                break
    return {
        "task": task,
        "method": method,
        "seed": seed,
        "solved": solved,
        "rollouts": rollouts,
        "wall_s": time.perf_counter() - started,
        "sim_s": 0.0,
        "kb_s": 0.0,
    }


TOY_GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Inv-kin"},
        {
            "id": "d",
            "role": "decision",
            "label": "#x",
            "domain": {"kind": "continuous", "low": [0.0], "high": [1.0]},
        },
    ],
    "edges": [{"source": "d", "target": "f", "label": "arg"}],
}


def toy_run_with_kb(task: str, method: str, seed: int, **kwargs: object) -> dict[str, object]:
    """`toy_run`, plus: note how many points the scenario's knowledge base holds at the start,
    then post one point to it (so a KB shared between scenarios would show; `points_posted`)."""
    from client import CpkbClient

    with CpkbClient(str(kwargs["kb_url"])) as client:
        points_before = client.get_kb(str(kwargs["kb"])).n_points
        client.post_points(
            str(kwargs["kb"]), [{"graph": TOY_GRAPH, "x": {"#x": [0.5]}, "feasible": False}]
        )
    result = toy_run(task, method, seed, **kwargs)  # type: ignore[arg-type]
    return {**result, "kb_points_before": points_before, "points_posted": 1}

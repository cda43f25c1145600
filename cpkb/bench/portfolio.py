"""A method without knowledge on N cores: N independent trees at once, the first binding wins.

`cpkb bench --cores N` gives every method N cores in all. A guided method's planner takes one
and its service the others; a method that keeps nothing beyond its tree (quasi-random) has no
service, so it takes them all as a portfolio: N runs of one task at once, one per core, each
seeded from the run's seed (tree 0 keeps it, so one tree is the plain run). The first tree to
find a binding ends the others. What the portfolio counts:

- rollouts: summed over the trees, each loser's as far as it had got when it was stopped (read
  after the winner's result arrived, so never fewer than it had spent while the winner ran);
- wall time: the winner's `wall_s` (the trees run at once); unsolved, the longest tree's;
- budget: each tree gets `max_rollouts // N` of it, so the trees together spend at most the
  run's cap, and an unsolved portfolio counts as the cap like any unsolved run.

The trees are processes of their own (`python -m cpkb.bench.portfolio`), started by the bench's
worker, which, a pool's daemon process, may not start a `multiprocessing` child.
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from cpkb.bench.records import RunResult, as_record

POLL_S = 0.02


class RolloutProgress(Protocol):
    """What a run function's `progress` callback receives (`planner.run.Progress`)."""

    rollouts: int


def tree_seeds(seed: int, trees: int) -> list[int]:
    """The trees' seeds: tree 0 keeps the run's seed, tree i the first word of the seed
    sequence of (seed, i), so every tree is reproducible from the run's seed alone."""
    return [seed] + [
        int(np.random.SeedSequence((seed, i)).generate_state(1)[0]) for i in range(1, trees)
    ]


@dataclass(frozen=True)
class TreeJob:
    """One tree of a portfolio, pickled to its process."""

    run_fn: Callable[..., RunResult]
    task: str
    method: str
    seed: int
    max_rollouts: int
    kwargs: Mapping[str, Any]
    core: int | None
    progress_path: str
    result_path: str
    parent_pid: int


@dataclass(frozen=True)
class Portfolio:
    """`run_fn` as `trees` independent trees at once (a run function itself); `cores`: the core
    of each tree (empty: the trees are not pinned)."""

    run_fn: Callable[..., RunResult]
    trees: int
    cores: Sequence[int] = field(default_factory=tuple)

    def __call__(
        self, task: str, method: str, seed: int, *, max_rollouts: int, **kwargs: Any
    ) -> dict[str, Any]:
        seeds = tree_seeds(seed, self.trees)
        budget = max(max_rollouts // self.trees, 1)
        with tempfile.TemporaryDirectory(prefix="cpkb-portfolio-") as tmp:
            trees = [
                _start(
                    TreeJob(
                        self.run_fn,
                        task,
                        method,
                        tree_seed,
                        budget,
                        kwargs,
                        self.cores[i] if i < len(self.cores) else None,
                        str(Path(tmp) / f"tree{i}.progress"),
                        str(Path(tmp) / f"tree{i}.json"),
                        os.getpid(),
                    )
                )
                for i, tree_seed in enumerate(seeds)
            ]
            try:
                results, winner = _race(trees)
            finally:
                for process, _ in trees:
                    _stop(process)
            counts = [
                _spent(results[i]) if i in results else _progress(job)
                for i, (_, job) in enumerate(trees)
            ]
        return _combined(results, winner, counts, seeds, list(self.cores))


def _stderr_path(job: TreeJob) -> Path:
    return Path(job.result_path).with_suffix(".err")


def _start(job: TreeJob) -> tuple[subprocess.Popen[bytes], TreeJob]:
    # The tree imports what the bench's own process could (a test's run function too).
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    with _stderr_path(job).open("wb") as stderr:
        process = subprocess.Popen(
            [sys.executable, "-m", "cpkb.bench.portfolio"],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=stderr,
            env=env,
        )
    assert process.stdin is not None
    process.stdin.write(pickle.dumps(job))
    process.stdin.close()
    return process, job


def _race(
    trees: Sequence[tuple[subprocess.Popen[bytes], TreeJob]],
) -> tuple[dict[int, dict[str, Any]], int | None]:
    """Wait until a tree solves (its index is the winner) or every tree has ended (None); the
    results of the trees that ended. A tree that failed fails the run."""
    results: dict[int, dict[str, Any]] = {}
    while len(results) < len(trees):
        time.sleep(POLL_S)
        ended = [i for i, (p, _) in enumerate(trees) if i not in results and p.poll() is not None]
        for i in ended:
            process, job = trees[i]
            path = Path(job.result_path)
            if process.returncode != 0 or not path.exists():
                stderr = _stderr_path(job).read_text(errors="replace")
                last = stderr.strip().splitlines()[-1:] or [f"exit status {process.returncode}"]
                raise RuntimeError(f"portfolio tree {i} (seed {job.seed}) failed: {last[0]}")
            results[i] = json.loads(path.read_text(encoding="utf-8"))
        solved = [i for i in ended if results[i]["solved"]]
        if solved:
            return results, min(solved, key=lambda i: float(results[i]["wall_s"]))
    return results, None


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            process.send_signal(signal.SIGKILL)
    process.wait()


def _spent(result: Mapping[str, Any]) -> int:
    """Every rollout a tree that ended ran (to its binding, or its whole budget)."""
    return int(result.get("rollouts_spent", result["rollouts"]))


def _progress(job: TreeJob) -> int:
    """The rollouts a stopped tree had reported (0 if it had not yet finished one)."""
    try:
        lines = Path(job.progress_path).read_text(encoding="utf-8").split()
    except FileNotFoundError:
        return 0
    return int(lines[-1]) if lines else 0


def _combined(
    results: Mapping[int, dict[str, Any]],
    winner: int | None,
    counts: Sequence[int],
    seeds: Sequence[int],
    cores: Sequence[int],
) -> dict[str, Any]:
    """The portfolio's record: the winner's (unsolved: the longest tree's) with the rollouts
    of every tree summed."""
    if winner is None:
        lead = max(results, key=lambda i: float(results[i]["wall_s"]))
        rollouts = sum(int(results[i]["rollouts"]) for i in results)
    else:
        lead = winner
        rollouts = int(results[winner]["rollouts"]) + sum(
            count for i, count in enumerate(counts) if i != winner
        )
    return {
        **results[lead],
        "rollouts": rollouts,
        "rollouts_spent": sum(counts),
        "portfolio": {
            "trees": len(seeds),
            "seeds": list(seeds),
            "cores": list(cores),
            "winner": winner,
            "rollouts": list(counts),
        },
    }


def _run_tree(job: TreeJob) -> None:
    """In the tree's process: run, reporting each rollout, and write the result."""
    from server.cpus import pin_process
    from server.lifeline import exit_with_parent

    exit_with_parent(job.parent_pid)
    if job.core is not None:
        pin_process(frozenset({job.core}))
    with open(job.progress_path, "w", encoding="utf-8") as log:

        def progress(p: RolloutProgress) -> None:
            log.write(f"{p.rollouts}\n")
            log.flush()

        result = job.run_fn(
            job.task,
            job.method,
            job.seed,
            max_rollouts=job.max_rollouts,
            progress=progress,
            **job.kwargs,
        )
    record = as_record(result)
    written = Path(job.result_path).with_suffix(".tmp")
    written.write_text(json.dumps(record, default=str), encoding="utf-8")
    written.replace(job.result_path)


if __name__ == "__main__":
    _run_tree(pickle.loads(sys.stdin.buffer.read()))

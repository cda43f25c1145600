"""What a planner's own MPF suggestion costs, replayed on requests recorded from real runs.

`record` runs transfer scenarios in this process (each on a fresh knowledge base of an embedded
service: the task's predecessors with cp-bo, 30 rollouts each, then the target until its first
binding or `--max-rollouts`) and keeps, for every suggestion the target's planner makes itself,
what went into it: the request, the models of its types as the planner held them (their points
since the last fetch not yet encoded), the pending points and the hints. `replay` answers each
recorded request again with the code it runs under (BLAS on one thread, as in a planner), timing
the planner thread's CPU, the process's CPU and the wall time (the best of `--repeats` passes
each) and hashing the answers: two commits that should answer alike must print
the same digest, and the time per request compares their cost on the same work.

    .venv/bin/python benchmarks/suggest_replay.py record \
        --tasks benchmarks/suites/dev/ws00/regrasp.yaml --seeds 7300-7301 --out /tmp/requests.pkl
    .venv/bin/python benchmarks/suggest_replay.py replay /tmp/requests.pkl --repeats 5

A recording is a pickle of this checkout's classes: replay it only with code you trust, and with
a commit whose planner models still read it.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import pickle
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from cpkb.bench.scenarios import seed_range
from planner.knowledge.local import one_blas_thread
from surrogate.suggest import TypeModel, suggest


class _Recorded:
    """A recorded planner's models as the `ModelSource` the suggestion reads; each replay
    starts from copies with nothing cached, as the planner had them before the request."""

    def __init__(self, models: Mapping[str, Any]) -> None:
        self._models = {type_id: _uncached(model) for type_id, model in models.items()}

    def model(self, type_id: str) -> TypeModel:
        held = self._models[type_id]
        return TypeModel(held.space, held.model(), held.version, held.n_fitted, 0)


class _FixedPending:
    """The pending points the planner's book held for the request; a replay adds none."""

    def __init__(self, points: Sequence[Mapping[str, Any]]) -> None:
        self._points = list(points)

    def for_request(self, key: str, type_ids: frozenset[str]) -> list[Mapping[str, Any]]:
        return list(self._points)

    def add(self, *args: object) -> None:
        return None


def _uncached(model: Any) -> Any:
    """A copy of a planner's `_Model` without its cached predictor or encodings."""
    fresh = copy.copy(model)
    fresh._combined, fresh._own_z, fresh._others_z = None, None, None
    fresh.own, fresh.others = list(model.own), list(model.others)
    return fresh


def record(tasks: list[str], seeds: range, out: Path, max_rollouts: int = 2000) -> int:
    import planner.knowledge.local as local
    from cpkb.bench.scenarios import predecessors
    from cpkb.embedded import embedded_service
    from planner.run import run_plan

    recorded: list[dict[str, Any]] = []
    answer = local.suggest_point

    def keeping(source: Any, request: Any, book: Any, **kwargs: Any) -> Any:
        types = {c.type_id for c in request.constraints}
        recorded.append(
            {
                "models": {t: _uncached(source._models[t]) for t in types},
                "request": request,
                "pending": list(book.for_request(kwargs["key"], frozenset(types))),
                **{k: list(v) if isinstance(v, list | tuple) else v for k, v in kwargs.items()},
            }
        )
        return answer(source, request, book, **kwargs)

    with (
        tempfile.TemporaryDirectory() as tmp,
        embedded_service(f"sqlite:///{tmp}/kb.db", planner_cores=1) as url,
    ):
        for task in tasks:
            for seed in seeds:
                kb = f"replay-{len(recorded)}-{seed}"
                for before in predecessors(task):
                    run_plan(
                        before,
                        "cp-bo",
                        seed,
                        kb_url=url,
                        kb=kb,
                        max_rollouts=30,
                        stop_at_first=False,
                    )
                local.suggest_point = keeping
                try:
                    run_plan(task, "cp-bo", seed, kb_url=url, kb=kb, max_rollouts=max_rollouts)
                finally:
                    local.suggest_point = answer
    out.write_bytes(pickle.dumps(recorded))
    print(f"recorded {len(recorded)} requests to {out}")
    return 0


def replay(path: Path, repeats: int) -> int:
    recorded = pickle.loads(path.read_bytes())
    if not recorded:
        print(f"{path}: no requests recorded", file=sys.stderr)
        return 2
    one_blas_thread()  # as the planner's process runs its suggestions
    digest = hashlib.sha256()
    passes: dict[str, list[float]] = {"thread CPU": [], "process CPU": [], "wall": []}
    clocks = {"thread CPU": time.thread_time, "process CPU": time.process_time}
    clocks["wall"] = time.perf_counter
    for n in range(repeats):
        spent = dict.fromkeys(passes, 0.0)
        for r in recorded:
            source, book = _Recorded(r["models"]), _FixedPending(r["pending"])
            options = {k: r[k] for k in ("key", "config", "hints", "preferred")}
            started = {name: clock() for name, clock in clocks.items()}
            answer = suggest(source, r["request"], book, **options)
            for name, clock in clocks.items():
                spent[name] += clock() - started[name]
            if n == 0:
                digest.update(json.dumps(answer.to_json(), sort_keys=True).encode())
        for name, total in spent.items():
            passes[name].append(total / len(recorded))
    print(f"{len(recorded)} requests; ms per request by pass:")
    for name, values in passes.items():
        shown = ", ".join(f"{1000 * s:.3f}" for s in values)
        print(f"  {name}: {shown}; best {1000 * min(values):.3f}")
    print(f"answers digest {digest.hexdigest()[:16]}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    keep = commands.add_parser("record", help="run transfer scenarios and keep their requests")
    keep.add_argument("--tasks", required=True, help="task files or shipped names, comma-separated")
    keep.add_argument("--seeds", type=seed_range, default=range(7300, 7302), help="FIRST-LAST")
    keep.add_argument("--out", type=Path, required=True)
    keep.add_argument(
        "--max-rollouts",
        type=int,
        default=2000,
        help="the target's budget (a hard target may find no binding in it); default 2000",
    )
    again = commands.add_parser("replay", help="answer recorded requests again, timed")
    again.add_argument("recording", type=Path)
    again.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    if args.command == "record":
        tasks = [t for t in args.tasks.split(",") if t]
        return record(tasks, args.seeds, args.out, args.max_rollouts)
    if not args.recording.is_file():
        print(f"{args.recording}: no such recording", file=sys.stderr)
        return 2
    if args.repeats < 1:
        print("--repeats must be at least 1", file=sys.stderr)
        return 2
    return replay(args.recording, args.repeats)


if __name__ == "__main__":
    sys.exit(main())

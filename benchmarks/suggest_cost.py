"""What one CP-BO suggestion costs, on the requests of a real planner run.

Runs `desk` (or `--task`) with `cp-bo` (PyBullet, an embedded service on a temporary SQLite
file) and records every suggest request it makes, waits for the surrogates to be fitted, then
replays the requests in-process against the same knowledge base with several optimiser settings
(raw samples only, or with 1, 2, 3, 5 or 20 NSGA-II generations): the median latency of the
service's `suggest` and the mean MPF of the answers. Also times the same requests over HTTP, to
show the transport.

    .venv/bin/python benchmarks/suggest_cost.py [--task desk] [--seed 1] [--out benchmarks/results]

Writes <out>/suggest_cost.json (desk) or <out>/suggest_cost-<task>.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from client import CpkbClient
from contract.models import SuggestIn
from cpkb.embedded import embedded_service
from planner.run import run_plan
from server.db import Store
from server.settings import ServiceSurrogateConfig
from server.surrogates import service
from server.surrogates.engine import SurrogateEngine
from surrogate.config import OptimizerConfig
from surrogate.pending import PendingBook

GENERATIONS = (0, 1, 2, 3, 5, 20)
REPEATS = 3


class RecordingClient(CpkbClient):
    """The typed client, keeping every suggest request."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.requests: list[SuggestIn] = []

    def suggest(self, kb: str, request: Any) -> Any:
        self.requests.append(SuggestIn.model_validate(request))
        return super().suggest(kb, request)


def record_run(url: str, task: str, seed: int) -> list[SuggestIn]:
    """One planner run whose client records its requests (`run_plan` imports the client class
    from the `client` package when it runs, so swapping it there is enough)."""
    import client as client_package

    made: list[RecordingClient] = []

    def recording(*args: Any, **kwargs: Any) -> RecordingClient:
        made.append(RecordingClient(*args, **kwargs))
        return made[-1]

    saved = client_package.CpkbClient
    client_package.CpkbClient = recording  # type: ignore[assignment,misc]
    try:
        run_plan(task, "cp-bo", seed, kb_url=url, kb="bench", suggest_in="service")
    finally:
        client_package.CpkbClient = saved  # type: ignore[misc]
    return [request for c in made for request in c.requests]


def replay(db_url: str, requests: list[SuggestIn]) -> list[dict[str, Any]]:
    engine = SurrogateEngine(Store.from_url(db_url), ServiceSurrogateConfig(fit_process=False))
    for request in requests:
        for constraint in request.constraints:
            engine.model("bench", constraint.type_id)
    engine.start()
    engine.wait_idle(300)
    rows = []
    try:
        for n_gen in GENERATIONS:
            optimizer = OptimizerConfig(generations=n_gen, mpf_margin=0.1, mpf_margin_abs=0.025)
            engine.config = ServiceSurrogateConfig(fit_process=False, optimizer=optimizer)
            seconds, values = [], []
            for _ in range(REPEATS):
                for request in requests:
                    engine.pending = PendingBook(0.0)  # each replay sees no earlier answer
                    started = time.perf_counter()
                    answer = service.suggest(engine, "bench", request)
                    seconds.append(time.perf_counter() - started)
                    values.append(answer.mpf)
            rows.append(
                {
                    "n_gen": n_gen,
                    "raw_samples": optimizer.raw_samples,
                    "median_ms": 1000 * statistics.median(seconds),
                    "mean_mpf": statistics.mean(values),
                }
            )
    finally:
        engine.stop()
    return rows


def over_http(url: str, requests: list[SuggestIn]) -> float:
    with CpkbClient(url) as kb:
        seconds = []
        for request in requests * REPEATS:
            started = time.perf_counter()
            kb.suggest("bench", request)
            seconds.append(time.perf_counter() - started)
    return 1000 * statistics.median(seconds)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="desk")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="cpkb-suggest-") as tmp:
        db_url = f"sqlite:///{Path(tmp) / 'kb.db'}"
        with embedded_service(db_url) as url:
            requests = record_run(url, args.task, args.seed)
            time.sleep(10)  # the service's own fits settle before it is timed
            http_ms = over_http(url, requests)
        if not requests:
            print("the run made no suggest request (solved before any type was active)")
            return 1
        rows = replay(db_url, requests)
    result = {
        "task": args.task,
        "seed": args.seed,
        "requests": len(requests),
        "http_median_ms": http_ms,
        "in_process": rows,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    name = Path(args.task).stem  # a task file is named by its stem
    path = args.out / ("suggest_cost.json" if name == "desk" else f"suggest_cost-{name}.json")
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

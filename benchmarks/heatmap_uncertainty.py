"""What showing the model's uncertainty costs the heat map: render time and SVG size of a type's
default 20 x 20 map (5 choices, 3 continuous dimensions, a real fit) with and without it.

Points lie on one choice's half of the cube (#pose[0] < 0.5; feasible where
#pose[0] + #pose[1] < 0.6, so that #pose[0] matters): the other choices and the other half are
unsure. Per size: the median of `--rounds` renders of each, and the share of cells hatched.

    nice -n 10 .venv/bin/python benchmarks/heatmap_uncertainty.py

Writes benchmarks/results/heatmap_uncertainty.json and prints a table.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import TypeAdapter

from contract.models import Domain
from server.dashboard.heatmap import choose_slice, continuous_dims, render_heatmap_svg
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder
from surrogate.models import warm_up
from surrogate.sources import InMemoryModels

RESULTS = Path(__file__).resolve().parent / "results"
CHOICES = ["front", "right", "top", "back", "left"]
RAW = {
    "#dir": {"kind": "categorical", "choices": CHOICES},
    "#pose": {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]},
}


def _median_ms(render: Callable[[], str], rounds: int) -> tuple[float, str]:
    times, svg = [], ""
    for _ in range(rounds):
        t0 = time.perf_counter()
        svg = render()
        times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times), svg


def measure(n: int, rounds: int) -> dict[str, Any]:
    rng = np.random.default_rng(n)
    observed = []
    for _ in range(n):
        pose = [0.5 * rng.random(), rng.random(), rng.random()]
        observed.append(({"#dir": "top", "#pose": pose}, pose[0] + pose[1] < 0.6))
    models = InMemoryModels()
    models.add("t", space_from_json(RAW), observed)
    model = models.model("t")
    encoder = SpaceEncoder(model.space)
    space = TypeAdapter(dict[str, Domain]).validate_python(RAW)
    dx, dy, _ = continuous_dims(space)
    held = choose_slice(space, observed)

    def predict(xs: list[dict]) -> list[float]:
        return model.predictor.proba(encoder.encode_points(xs)).tolist()

    def judge(xs: list[dict]) -> tuple[list[float], list[float]]:
        z = encoder.encode_points(xs)
        return model.predictor.proba(z).tolist(), model.predictor.uncertainty(z).tolist()

    plain_ms, plain = _median_ms(
        lambda: render_heatmap_svg(space, dx, dy, predict, observed, held=held), rounds
    )
    shown_ms, shown = _median_ms(
        lambda: render_heatmap_svg(space, dx, dy, predict, observed, held=held, judge=judge),
        rounds,
    )
    cells = shown.count('class="cp-cell"')
    top = shown.split('data-panel="#dir=top"')[1].split("</g>")[0]
    return {
        "points": n,
        "predictor": type(model.predictor).__name__,
        "render_ms_without": round(plain_ms, 1),
        "render_ms_with": round(shown_ms, 1),
        "svg_kb_without": round(len(plain) / 1000, 1),
        "svg_kb_with": round(len(shown) / 1000, 1),
        "hatched_share": round(shown.count("data-unsure") / cells, 3),
        "hatched_share_top_panel": round(
            top.count("data-unsure") / top.count('class="cp-cell"'), 3
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="60,1000")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--out", type=Path, default=RESULTS / "heatmap_uncertainty.json")
    args = parser.parse_args()
    warm_up()
    rows = [measure(int(n), args.rounds) for n in args.sizes.split(",")]
    args.out.write_text(
        json.dumps(
            {
                "when": datetime.now(UTC).isoformat(timespec="seconds"),
                "machine": platform.platform(),
                "rounds": args.rounds,
                "rows": rows,
            },
            indent=2,
        )
        + "\n"
    )
    for row in rows:
        print(row)


if __name__ == "__main__":
    main()

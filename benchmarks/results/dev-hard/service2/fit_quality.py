"""Held-out AUC and CPU seconds of cold and warm classifier fits over several synthetic types.

The scratch script behind fit_quality-*.json (see provenance.txt); from the repository root:

    PYTHONPATH=.:benchmarks python benchmarks/results/dev-hard/service2/fit_quality.py OUT \
        disc5:10000,rare5:10000,place:3000,clear:1000,reach:300,clear:60,place:60
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from fit_scaling import constraint
from sklearn.metrics import roc_auc_score

from surrogate.domains import space_from_json
from surrogate.encoding import encoder_for
from surrogate.models import fit_classifier, use_threads, warm_up

DIRS = ["front", "right", "top", "back", "left"]
SPACE = space_from_json(
    {
        "#dir": {"kind": "categorical", "choices": DIRS},
        "#pose": {"kind": "continuous", "low": [0, 0, 0], "high": [1, 1, 1]},
    }
)
HELD_OUT = 5000


def synth(kind: str, n: int, seed: int) -> tuple[np.ndarray, ...]:
    """`n` training and HELD_OUT held-out points of a synthetic type, labelled."""
    rng = np.random.default_rng(seed)
    if kind in ("disc5", "rare5"):
        z = rng.random((n + HELD_OUT, 5))
        y = constraint(z) if kind == "disc5" else np.hypot(z[:, 0] - 0.3, z[:, 1] - 0.6) < 0.12
    else:
        d, p = rng.integers(0, 5, n + HELD_OUT), rng.random((n + HELD_OUT, 3))
        points = [{"#dir": DIRS[i], "#pose": list(q)} for i, q in zip(d, p, strict=True)]
        z = encoder_for(SPACE).encode_points(points)
        disc = np.hypot(p[:, 1] - 0.5, p[:, 2] - 0.5)
        y = {
            "reach": (p[:, 0] > 0.35) & (d != 3),
            "clear": (disc < 0.3) | (p[:, 0] > 0.8),
            "place": (p[:, 0] > 0.3) & (disc < 0.45) & (d != 3),
        }[kind]
    return z[:n], y[:n], z[n:], y[n:]


def main() -> None:
    use_threads(1)
    warm_up()
    rows = []
    for case in sys.argv[2].split(","):
        kind, n = case.split(":")[0], int(case.split(":")[1])
        for seed in (0, 1):
            z, y, zt, yt = synth(kind, n, seed)
            t = time.process_time()
            cold = fit_classifier(z, y, seed=seed)
            cold_cpu = time.process_time() - t
            k = int(0.95 * n)
            earlier = fit_classifier(z[:k], y[:k], seed=seed)
            t = time.process_time()
            warm = fit_classifier(z, y, seed=seed, warm=earlier)
            warm_cpu = time.process_time() - t
            instant = fit_classifier(z, y, seed=seed, max_iters=30) if n <= 128 else None
            row = {"kind": kind, "n": n, "seed": seed, "cold_cpu": round(cold_cpu, 3)}
            row["cold_auc"] = round(roc_auc_score(yt, cold.predictor.proba(zt)), 4)
            row["warm_cpu"] = round(warm_cpu, 3)
            row["warm_auc"] = round(roc_auc_score(yt, warm.predictor.proba(zt)), 4)
            if instant is not None:
                row["instant_auc"] = round(roc_auc_score(yt, instant.predictor.proba(zt)), 4)
            rows.append(row)
            print(json.dumps(row), flush=True)
    Path(sys.argv[1]).write_text(json.dumps(rows) + "\n")


if __name__ == "__main__":
    main()

"""A surrogate fit killed half-way leaves no broken model behind, and no orphan.

Fits run in a child process of the server and their results live only in the server's memory,
rebuilt from the stored points (so a whole-server kill, tested in test_crash_safety, leaves no
model at all to break). The kill that matters is the fit worker dying mid-fit (the OOM killer):
the type keeps answering from its previous complete model, and the next fit covers every point.
"""

from __future__ import annotations

import math
import os
import signal
import time
from pathlib import Path

import httpx
import pytest
from killable_server import KillableServer, alive, fit_workers

DIRS = ["front", "right", "top", "back", "left"]
GRAPH = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Plan-motion"},
        {
            "id": "d",
            "role": "decision",
            "label": "#dir",
            "domain": {"kind": "categorical", "choices": DIRS},
        },
        {
            "id": "p",
            "role": "decision",
            "label": "#pose",
            "domain": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
        },
    ],
    "edges": [
        {"source": "d", "target": "f", "label": "feeds"},
        {"source": "p", "target": "f", "label": "feeds"},
    ],
}
PROBES = [{"#dir": d, "#pose": [u, 0.5]} for d in ("top", "back") for u in (0.1, 0.9)]


def batch(start: int, n: int) -> dict:
    points = []
    for i in range(start, start + n):
        pose = [((i * 0.618) % 1.0), ((i * 0.382) % 1.0)]
        direction = DIRS[i % 5]
        feasible = pose[0] > 0.4 and direction != "back"
        points.append(
            {
                "graph": GRAPH,
                "x": {"#dir": direction, "#pose": pose},
                "feasible": feasible,
                "key": f"p{i}",
            }
        )
    return {"points": points}


def surrogate(http: httpx.Client, type_id: str) -> dict:
    detail = http.get(f"/v1/kbs/default/types/{type_id}")
    assert detail.status_code == 200, detail.text
    return detail.json()["surrogate"] or {}


def wait_fitted(http: httpx.Client, type_id: str, n_points: int, timeout: float = 120) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = surrogate(http, type_id)
        if state.get("status") == "ready" and state.get("n_fitted") == n_points:
            return state
        time.sleep(0.2)
    raise AssertionError(f"no complete fit of {n_points} points: {surrogate(http, type_id)}")


def wait_fitting(http: httpx.Client, type_id: str, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while surrogate(http, type_id).get("status") != "fitting":
        assert time.monotonic() < deadline, "the fit never started"
        time.sleep(0.02)


def predict(http: httpx.Client, type_id: str) -> list[float]:
    response = http.post(f"/v1/kbs/default/types/{type_id}/predict", json={"x": PROBES})
    assert response.status_code == 200, response.text
    p = response.json()["p_feasible"]
    assert len(p) == len(PROBES) and all(math.isfinite(v) and 0 <= v <= 1 for v in p)
    return p


def suggest_works(http: httpx.Client, type_id: str) -> None:
    body = {
        "space": {"dir": GRAPH["nodes"][1]["domain"], "pose": GRAPH["nodes"][2]["domain"]},
        "constraints": [{"type_id": type_id, "bind": {"#dir": "dir", "#pose": "pose"}}],
        "seed": 3,
    }
    response = http.post("/v1/kbs/default/suggest", json=body)
    assert response.status_code == 200, response.text
    assert 0 <= response.json()["mpf"] <= 1


@pytest.mark.slow
def test_killed_fits_leave_complete_models(sqlite_url: str, tmp_path: Path) -> None:
    server = KillableServer(sqlite_url, tmp_path)
    server.start()
    try:
        with httpx.Client(base_url=server.url, timeout=60) as http:
            posted = http.post("/v1/kbs/default/points", json=batch(0, 100))
            type_id = posted.json()["results"][0]["type_id"]
            first = wait_fitted(http, type_id, 100)
            before = predict(http, type_id)

            # The fit worker dies half-way through the next fit.
            assert http.post("/v1/kbs/default/points", json=batch(100, 300)).status_code == 201
            wait_fitting(http, type_id)
            assert server.proc is not None
            workers = fit_workers(server.proc.pid)
            assert workers, "no fit worker process found"
            for pid in workers:
                os.kill(pid, signal.SIGKILL)
            during = predict(http, type_id)
            state = surrogate(http, type_id)
            assert state["status"] in ("fitting", "ready"), state
            assert state["n_fitted"] in (first["n_fitted"], 400), state
            if state["n_fitted"] == first["n_fitted"]:
                # The answers weigh in the 300 new points (RecentPoints); the fit is the first.
                assert state["lengthscales"] == first["lengthscales"], "a half-done fit was used"
                assert len(during) == len(before) and all(0 <= p <= 1 for p in during)
            wait_fitted(http, type_id, 400)
            assert not set(workers) & set(fit_workers(server.proc.pid)), "worker not replaced"
            predict(http, type_id)
            suggest_works(http, type_id)

        # A SIGKILLed server cannot stop its fit worker: the worker must notice and leave.
        workers = fit_workers(server.proc.pid)
        assert workers
        server.proc.send_signal(signal.SIGKILL)
        server.proc.wait(timeout=10)
        deadline = time.monotonic() + 120  # it polls its parent; a loaded machine is slow
        while any(alive(pid) for pid in workers):
            assert time.monotonic() < deadline, "the fit worker outlived its server"
            time.sleep(0.1)
    finally:
        server.stop()

"""Two synthetic constraint types over (#dir, #pose), with their ground truth, for suggest tests."""

from __future__ import annotations

from typing import Any

import numpy as np
from service_support import DIR_DOMAIN, POSE_DOMAIN, make_graph

REACH = make_graph("Inv-kin", ("shelf",))
CLEAR = make_graph("Plan-motion", ("box1",))
SPACE = {"d": DIR_DOMAIN, "p": POSE_DOMAIN}
BIND = {"#dir": "d", "#pose": "p"}


def reach_ok(x: dict[str, Any]) -> bool:
    return x["#pose"][0] > 0.5


def clear_ok(x: dict[str, Any]) -> bool:
    return x["#pose"][1] < 0.5 and x["#dir"] != "top"


def points(n: int, seed: int = 0) -> list[dict[str, Any]]:
    """`n` random decisions, each posted to both types with its true label."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x = {
            "#dir": DIR_DOMAIN["choices"][int(rng.integers(5))],
            "#pose": [float(rng.random()), float(rng.random()), float(rng.uniform(-3, 3))],
        }
        out.append({"graph": REACH, "x": x, "feasible": reach_ok(x)})
        out.append({"graph": CLEAR, "x": x, "feasible": clear_ok(x)})
    return out


def suggest_body(type_ids: list[str], **extra: Any) -> dict[str, Any]:
    constraints = [{"type_id": t, "bind": dict(BIND)} for t in type_ids]
    return {"space": SPACE, "constraints": constraints, **extra}


def as_decision(x: dict[str, Any]) -> dict[str, Any]:
    return {"#dir": x["d"], "#pose": x["p"]}


def make_client(sqlite_url: str, **surrogate: Any) -> Any:
    """A test client of a service whose surrogate knobs are `surrogate` (fits in a thread)."""
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.settings import Settings

    config = Settings(database_url=sqlite_url, surrogate={"fit_process": False, **surrogate})
    return TestClient(create_app(config))


def post_points(client: Any, n: int, seed: int = 0) -> list[str]:
    answer = client.post("/v1/kbs/default/points", json={"points": points(n, seed)})
    assert answer.status_code == 201
    return sorted({r["type_id"] for r in answer.json()["results"]})

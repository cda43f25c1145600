"""The work one request may ask for is bounded: the distinct graphs a match or a post has
hashed hold at most CPKB_MAX_REQUEST_GRAPH_NODES nodes (413 beyond, nothing stored), and
while heavy requests run, the health check and reads still answer."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from service_support import make_graph, make_point, run_live_server

from contract.models import MAX_NODES
from server.app import create_app
from server.settings import DEFAULT_GRAPH_NODES, Settings

MATCH = "/v1/kbs/default/types/match"


def big_graph(i: int, n: int = MAX_NODES) -> dict[str, Any]:
    """A failure graph of `n` nodes, distinct for each `i` (its failure's label)."""
    nodes = [
        {"id": "f", "role": "failure", "label": f"F{i}"},
        {
            "id": "d",
            "role": "decision",
            "label": "#k",
            "domain": {"kind": "categorical", "choices": ["a", "b"]},
        },
    ]
    edges = [{"source": "d", "target": "f", "label": "feeds"}]
    for j in range(n - 2):
        nodes.append({"id": f"c{j}", "role": "context", "label": f"b{j % 7}"})
        other = (j * 5 + i) % (n - 2)
        target = "f" if j % 3 == 0 or other == j else f"c{other}"
        edges.append({"source": f"c{j}", "target": target, "label": "touches"})
    return {"nodes": nodes, "edges": edges}


OVER_BUDGET = DEFAULT_GRAPH_NODES // MAX_NODES + 1  # distinct 64-node graphs, one too many


def test_a_match_or_post_over_the_node_budget_is_413(core_client: Any) -> None:
    graphs = [big_graph(i) for i in range(OVER_BUDGET)]
    refused = core_client.post(MATCH, json={"graphs": graphs})
    assert refused.status_code == 413, refused.text[:300]
    assert "CPKB_MAX_REQUEST_GRAPH_NODES" in refused.json()["detail"]

    points = [{"graph": g, "x": {"#k": "a"}, "feasible": True} for g in graphs]
    posted = core_client.post("/v1/kbs/default/points", json={"points": points})
    assert posted.status_code == 413, posted.text[:300]
    assert core_client.get("/v1/kbs/default").json()["n_points"] == 0

    # Within the budget: the same graph many times counts once; a planner's 500 small graphs.
    same = core_client.post(MATCH, json={"graphs": [graphs[0]] * 1000})
    assert same.status_code == 200
    small = [make_graph(context=(f"body{i}",)) for i in range(500)]
    assert core_client.post(MATCH, json={"graphs": small}).status_code == 200
    many = [make_point(i, graph=make_graph(context=(f"b{i % 50}",))) for i in range(1000)]
    assert core_client.post("/v1/kbs/default/points", json={"points": many}).status_code == 201


def test_the_budget_is_a_setting(sqlite_url: str) -> None:
    settings = Settings(database_url=sqlite_url, surrogate_enabled=False)
    settings.max_request_graph_nodes = 2 * MAX_NODES
    with TestClient(create_app(settings)) as client:
        two = client.post(MATCH, json={"graphs": [big_graph(0), big_graph(1)]})
        three = client.post(MATCH, json={"graphs": [big_graph(i) for i in range(3)]})
    assert two.status_code == 200 and three.status_code == 413


@pytest.mark.slow
def test_health_and_reads_answer_while_heavy_matches_run(sqlite_url: str, tmp_path: Path) -> None:
    env = {"CPKB_SURROGATE__ENABLED": "false"}
    with run_live_server(sqlite_url, tmp_path / "server.log", env=env) as live:
        done: list[int] = []

        def match(offset: int) -> None:
            # Distinct graphs each time, so that no cache makes them cheap.
            body = {"graphs": [big_graph(i + offset) for i in range(OVER_BUDGET - 1)]}
            done.append(httpx.post(live.url + MATCH, json=body, timeout=600).status_code)

        senders = [threading.Thread(target=match, args=(1000 * (k + 1),)) for k in range(6)]
        for t in senders:
            t.start()
        answers = []
        while len(answers) < 10:
            answers.append(httpx.get(live.url + "/healthz", timeout=600).status_code)
            answers.append(httpx.get(live.url + "/v1/kbs", timeout=600).status_code)
        finished_meanwhile = len(done)
        for t in senders:
            t.join(timeout=600)
    assert answers == [200] * 10
    assert finished_meanwhile < len(senders), "the heavy requests ended before the reads"
    assert done == [200] * len(senders)

"""The typed client against a real server on a loopback port."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import pytest
from service_support import make_graph, make_point

from client import BadRequest, Conflict, CpkbClient, NotFound, ServiceUnavailable
from contract.models import PointIn
from cpkb.embedded import free_port

Kb = tuple[CpkbClient, str]


def test_health_and_knowledge_bases(kb_client: Kb) -> None:
    client, kb = kb_client
    assert client.health().status == "ok"
    names = [k.name for k in client.list_kbs()]
    assert "default" in names and kb in names
    with pytest.raises(Conflict, match="already exists"):
        client.create_kb(kb)
    assert client.create_kb(kb, exist_ok=True).name == kb
    client.delete_kb(kb)
    with pytest.raises(NotFound, match=f"knowledge base '{kb}' not found") as info:
        client.get_kb(kb)
    assert info.value.status == 404
    assert info.value.detail == f"knowledge base '{kb}' not found"


def test_post_points_gives_every_point_a_key_and_batches(kb_client: Kb) -> None:
    client, kb = kb_client
    points = [make_point(i, key=None) for i in range(1500)]
    results = client.post_points(kb, points, batch_size=1000)
    assert len(results) == 1500 and len({r.point_id for r in results}) == 1500
    assert results[0].new_type and not any(r.new_type for r in results[1:])
    stored = list(client.iter_points(kb, results[0].type_id, page_size=400))
    assert len(stored) == 1500
    assert all(p.key for p in stored) and len({p.key for p in stored}) == 1500


def test_reposting_keyed_points_stores_nothing_twice(kb_client: Kb) -> None:
    client, kb = kb_client
    points = [PointIn.model_validate(make_point(i)) for i in range(20)]
    first = client.post_points(kb, points)
    again = client.post_points(kb, points, batch_size=7)
    assert again == first
    assert client.get_kb(kb).n_points == 20


def test_types_points_and_csv(kb_client: Kb, tmp_path: Path) -> None:
    client, kb = kb_client
    ik, motion = make_graph(), make_graph(failure="Plan-motion", context=("shelf",))
    client.post_points(kb, [make_point(i, graph=ik, task="desk", run="r1") for i in range(9)])
    client.post_points(kb, [make_point(i, graph=motion) for i in range(4)])
    types = {t.failure: t for t in client.list_types(kb)}
    assert types["Inv-kin"].n_points == 9 and types["Plan-motion"].n_points == 4
    detail = client.get_type(kb, types["Plan-motion"].type_id)
    assert detail.context == ["shelf"] and set(detail.space) == {"#dir", "#pose"}
    page = client.list_points(kb, types["Inv-kin"].type_id, limit=4)
    assert len(page.points) == 4 and page.next_cursor is not None
    assert page.points[0].source == {"task": "desk", "run": "r1"}
    text = client.export_csv(kb, types["Inv-kin"].type_id, tmp_path / "ik.csv")
    assert (tmp_path / "ik.csv").read_bytes().decode() == text
    assert len(text.strip().splitlines()) == 10
    matched = client.match_types(kb, [ik, make_graph(failure="Move-Pick")])
    assert [(m.exists, m.n_points) for m in matched] == [(True, 9), (False, 0)]


def test_4xx_raise_with_the_servers_detail(kb_client: Kb) -> None:
    client, kb = kb_client
    bad = make_point(1)
    bad["x"]["#dir"] = "up"
    with pytest.raises(BadRequest, match=r"points\[0\].x.#dir") as info:
        client.post_points(kb, [bad])
    assert info.value.status == 422
    client.post_points(kb, [make_point(1)])
    wider = make_graph(pose_domain={"kind": "continuous", "low": [0, 0, -3], "high": [2, 1, 3]})
    with pytest.raises(Conflict, match="#pose"):
        client.post_points(kb, [make_point(1, graph=wider)])
    with pytest.raises(NotFound):
        client.list_types("no-such-kb")
    with pytest.raises(BadRequest, match="limit"):
        client.list_points(kb, "whatever", limit=0)


def test_an_unreachable_server_is_service_unavailable_after_retries() -> None:
    url = f"http://127.0.0.1:{free_port()}"
    with (
        CpkbClient(url, retries=2, backoff=0.01) as client,
        pytest.raises(ServiceUnavailable, match="cannot reach") as info,
    ):
        client.health()
    assert info.value.status is None


def test_5xx_is_retried_and_4xx_is_not() -> None:
    """A scripted transport: a real server will not fail on request."""
    calls: list[str] = []
    answers = iter([503, 502, 200, 404])

    def handler(request: httpx.Request) -> httpx.Response:
        calls.append(request.url.path)
        status = next(answers)
        body = {"status": "ok", "version": "x", "database": "sqlite"} if status == 200 else {}
        return httpx.Response(status, content=json.dumps({"detail": "no", **body}))

    transport = httpx.MockTransport(handler)
    with CpkbClient("http://kb", retries=3, backoff=0.001, transport=transport) as client:
        assert client.health().status == "ok"
        assert len(calls) == 3
        with pytest.raises(NotFound):
            client.list_kbs()
        assert len(calls) == 4

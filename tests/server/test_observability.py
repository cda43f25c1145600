"""Metrics at /metrics and structured logs, over a real app and database."""

from __future__ import annotations

import io
import json
import logging
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from prometheus_client.parser import text_string_to_metric_families

from server.observability import (
    REGISTRY,
    JsonFormatter,
    configure_json_logging,
    record_fit,
)
from tests.service_support import make_graph, make_point
from tests.wait_support import PATIENCE_S, wait_until


def _value(name: str, **labels: str) -> float:
    return REGISTRY.get_sample_value(name, labels) or 0.0


def _scrape(client: Any) -> dict[str, list[Any]]:
    response = client.get("/metrics")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/plain")
    return {f.name: f.samples for f in text_string_to_metric_families(response.text)}


def test_requests_are_counted_and_timed_by_route_template(app_client: Any) -> None:
    route = "/v1/kbs/{kb}/types"
    ok = {"method": "GET", "route": route, "status": "200"}
    missing = {"method": "GET", "route": route, "status": "404"}
    before_ok, before_missing = (
        _value("cpkb_http_requests_total", **ok),
        _value("cpkb_http_requests_total", **missing),
    )
    before_timed = _value("cpkb_http_request_duration_seconds_count", method="GET", route=route)
    for _ in range(3):
        assert app_client.get("/v1/kbs/default/types").status_code == 200
    assert app_client.get("/v1/kbs/nope/types").status_code == 404
    assert _value("cpkb_http_requests_total", **ok) - before_ok == 3
    assert _value("cpkb_http_requests_total", **missing) - before_missing == 1
    assert (
        _value("cpkb_http_request_duration_seconds_count", method="GET", route=route) - before_timed
        == 4
    )
    families = _scrape(app_client)
    routes = {s.labels.get("route") for s in families["cpkb_http_requests"]}
    assert route in routes
    assert not any("default" in r or "nope" in r for r in routes if r)


def test_unknown_paths_share_one_label(app_client: Any) -> None:
    labels = {"method": "GET", "route": "<unmatched>", "status": "404"}
    before = _value("cpkb_http_requests_total", **labels)
    for i in range(5):
        assert app_client.get(f"/no/such/path/{i}").status_code == 404
    assert _value("cpkb_http_requests_total", **labels) - before == 5


def test_points_ingested_counts_stored_points_only(app_client: Any) -> None:
    app_client.post("/v1/kbs", json={"name": "metrics-kb"})
    before = _value("cpkb_points_ingested_total", kb="metrics-kb")
    before_types = _value("cpkb_types_created_total", kb="metrics-kb")
    points = [make_point(i, key=f"k{i}") for i in range(12)]
    assert app_client.post("/v1/kbs/metrics-kb/points", json={"points": points}).status_code == 201
    # the same keys again: nothing new is stored, nothing is counted
    assert app_client.post("/v1/kbs/metrics-kb/points", json={"points": points}).status_code == 201
    assert _value("cpkb_points_ingested_total", kb="metrics-kb") - before == 12
    assert _value("cpkb_types_created_total", kb="metrics-kb") - before_types == 1


def test_store_gauges_follow_the_database(app_client: Any) -> None:
    app_client.post("/v1/kbs", json={"name": "gauged"})
    other = make_graph("Plan-motion", ("shelf",))
    points = [make_point(i) for i in range(5)] + [make_point(i, graph=other) for i in range(2)]
    app_client.post("/v1/kbs/gauged/points", json={"points": points})
    families = _scrape(app_client)
    types = {s.labels["kb"]: s.value for s in families["cpkb_active_types"]}
    stored = {s.labels["kb"]: s.value for s in families["cpkb_points_stored"]}
    assert types["gauged"] == 2 and stored["gauged"] == 7
    assert types["default"] == 0


def _beyond_top_bucket(name: str) -> float:
    """Observations of histogram `name` above its largest finite bucket."""
    buckets = {
        sample.labels["le"]: sample.value
        for family in REGISTRY.collect()
        for sample in family.samples
        if sample.name == f"{name}_bucket"
    }
    top = max((le for le in buckets if le != "+Inf"), key=float)
    return buckets["+Inf"] - buckets[top]


def test_fits_are_counted_with_their_duration() -> None:
    # The counters are the process's, and engines of other tests may fit meanwhile: the fits
    # recorded here take longer and train on more points than any test's real fit, so the
    # histograms' top ranges count them alone; the counters can only have grown by at least them.
    before_ok = _value("cpkb_surrogate_fits_total", outcome="ok")
    before_failed = _value("cpkb_surrogate_fits_total", outcome="error")
    before_long = _beyond_top_bucket("cpkb_surrogate_fit_duration_seconds")
    before_large = _beyond_top_bucket("cpkb_surrogate_fit_points")
    record_fit(7500.0, 120_000)
    record_fit(9000.0, 240_000)
    record_fit(3.0, 10, ok=False)
    assert _value("cpkb_surrogate_fits_total", outcome="ok") - before_ok >= 2
    assert _value("cpkb_surrogate_fits_total", outcome="error") - before_failed >= 1
    assert _beyond_top_bucket("cpkb_surrogate_fit_duration_seconds") - before_long == 2
    assert _beyond_top_bucket("cpkb_surrogate_fit_points") - before_large == 2


def test_every_metric_name_is_prefixed(app_client: Any) -> None:
    app_client.get("/healthz")
    names = set(_scrape(app_client))
    assert names and all(name.startswith("cpkb_") for name in names)
    assert {
        "cpkb_http_requests",
        "cpkb_http_request_duration_seconds",
        "cpkb_points_ingested",
        "cpkb_surrogate_fits",
        "cpkb_surrogate_fit_duration_seconds",
        "cpkb_suggest_duration_seconds",
        "cpkb_active_types",
    } <= names


def test_access_log_is_one_json_object_per_request(app_client: Any) -> None:
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(JsonFormatter())
    logger = logging.getLogger("cpkb.access")
    logger.addHandler(handler)
    old_level = logger.level
    logger.setLevel(logging.INFO)
    try:
        app_client.get("/v1/kbs/default/types")
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old_level)
    records = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert len(records) == 1
    record = records[0]
    assert record["message"] == "request" and record["logger"] == "cpkb.access"
    assert record["route"] == "/v1/kbs/{kb}/types" and record["path"] == "/v1/kbs/default/types"
    assert record["status"] == 200 and record["duration_ms"] > 0
    assert record["level"] == "info" and record["time"].endswith("+00:00")


def test_configured_logging_writes_json_lines_with_extras_and_exceptions(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    stream = io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    try:
        configure_json_logging("info")
        configure_json_logging("info")  # idempotent: still one handler
        log = logging.getLogger("cpkb.test")
        log.info("fitted", extra={"type_id": "abc", "seconds": 1.25})
        try:
            raise ValueError("boom")
        except ValueError:
            log.exception("fit failed")
    finally:
        root.handlers[:] = handlers
        root.setLevel(level)
    lines = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert [line["message"] for line in lines] == ["fitted", "fit failed"]
    assert lines[0]["type_id"] == "abc" and lines[0]["seconds"] == 1.25
    assert "ValueError: boom" in lines[1]["exception"] and lines[1]["level"] == "error"


def test_no_created_series_double_the_count(app_client: Any) -> None:
    app_client.get("/healthz")
    samples = [s.name for samples in _scrape(app_client).values() for s in samples]
    assert "cpkb_http_requests_total" in samples
    assert not [name for name in samples if name.endswith("_created")]


def test_answers_before_routing_and_plain_routes_are_labelled_by_route(db_url: str) -> None:
    from fastapi.testclient import TestClient

    from server.app import create_app
    from server.settings import Settings

    app = create_app(Settings(database_url=db_url, max_body_bytes=2048))
    too_large = {"method": "POST", "route": "/v1/kbs/{kb}/points", "status": "413"}
    docs = {"method": "GET", "route": "/docs", "status": "200"}
    wrong_method = {"method": "PUT", "route": "/v1/kbs", "status": "405"}
    unmatched = {"method": "POST", "route": "<unmatched>", "status": "413"}
    watched = (too_large, docs, wrong_method)
    before = [_value("cpkb_http_requests_total", **labels) for labels in watched]
    before_unmatched = _value("cpkb_http_requests_total", **unmatched)
    with TestClient(app) as client:
        body = {"points": [make_point(i) for i in range(40)]}
        assert client.post("/v1/kbs/default/points", json=body).status_code == 413
        assert client.get("/docs").status_code == 200
        assert client.put("/v1/kbs", json={}).status_code == 405
    after = [_value("cpkb_http_requests_total", **labels) for labels in watched]
    assert [a - b for a, b in zip(after, before, strict=True)] == [1, 1, 1]
    assert _value("cpkb_http_requests_total", **unmatched) == before_unmatched


def test_planner_reported_suggest_timings_are_counted_once(app_client: Any) -> None:
    name = "cpkb_planner_suggest_duration_seconds"
    before_n, before_sum = _value(f"{name}_count"), _value(f"{name}_sum")
    points = [make_point(i, key=f"timed{i}") for i in range(3)]
    points[0]["source"] = {"run": "r1", "local_suggest_s": [0.02, 0.5]}
    # Not timings: a negative, a string, a boolean and one of over an hour are left out.
    points[1]["source"] = {"run": "r1", "local_suggest_s": [-1, "fast", True, 7200, 0.25]}
    points[2]["source"] = {"run": "r1", "local_suggest_s": 0.3}
    for _ in range(2):  # the retry stores nothing new and counts nothing again
        response = app_client.post("/v1/kbs/default/points", json={"points": points})
        assert response.status_code == 201
    assert _value(f"{name}_count") - before_n == 3
    assert _value(f"{name}_sum") - before_sum == pytest.approx(0.77)
    assert _value(f"{name}_bucket", le="0.025") - _value(f"{name}_bucket", le="0.01") >= 1


def _gauges(client: Any, kb: str) -> dict[str, float]:
    families = _scrape(client)
    return {
        name: next((s.value for s in families[name] if s.labels["kb"] == kb), 0.0)
        for name in (
            "cpkb_surrogate_fit_backlog",
            "cpkb_surrogate_unfitted_points",
            "cpkb_surrogate_stale_model_age_seconds",
        )
    }


def test_fit_backlog_and_model_staleness_gauges_follow_the_engine(
    app_client: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    engine = app_client.app.state.surrogates
    app_client.post("/v1/kbs", json={"name": "lagging"})
    points = [make_point(i, feasible=i % 2 == 0) for i in range(12)]
    assert app_client.post("/v1/kbs/lagging/points", json={"points": points}).status_code == 201
    assert engine.wait_idle(timeout=PATIENCE_S)
    assert set(_gauges(app_client, "lagging").values()) == {0.0}
    # The next fit is held, so the points posted meanwhile lag behind the served model.
    release = threading.Event()
    fit = engine._fit

    def held_fit(*args: Any) -> Any:
        release.wait(timeout=PATIENCE_S)
        return fit(*args)

    monkeypatch.setattr(engine, "_fit", held_fit)
    more = [make_point(i, feasible=i % 2 == 1) for i in range(12, 20)]
    assert app_client.post("/v1/kbs/lagging/points", json={"points": more}).status_code == 201
    lagging = wait_until(
        lambda: (g := _gauges(app_client, "lagging"))["cpkb_surrogate_unfitted_points"] and g,
        what="the unfitted points to show",
    )
    assert lagging["cpkb_surrogate_unfitted_points"] == 8
    assert lagging["cpkb_surrogate_fit_backlog"] == 1
    assert lagging["cpkb_surrogate_stale_model_age_seconds"] >= 0
    release.set()
    assert engine.wait_idle(timeout=PATIENCE_S)
    assert set(_gauges(app_client, "lagging").values()) == {0.0}


@pytest.mark.slow
def test_a_served_service_writes_json_access_logs_and_get_or_create_adds_no_409(
    sqlite_url: str, tmp_path: Path
) -> None:
    from client import CpkbClient
    from tests.service_support import run_live_server

    log = tmp_path / "server.log"
    with run_live_server(sqlite_url, log) as server, CpkbClient(server.url) as client:
        for _ in range(3):  # as every `cpkb plan` on a shared knowledge base does
            assert client.create_kb("shared", exist_ok=True).name == "shared"
        assert client.create_kb("default", exist_ok=True).name == "default"
        metrics = client.request("GET", "/metrics").text
        families = {f.name: f.samples for f in text_string_to_metric_families(metrics)}
    statuses = {
        s.labels["status"]
        for s in families["cpkb_http_requests"]
        if s.labels["route"] == "/v1/kbs" and s.labels["method"] == "POST"
    }
    assert statuses == {"201"}
    records = [json.loads(line) for line in log.read_text().splitlines() if line.startswith("{")]
    access = [r for r in records if r["logger"] == "cpkb.access"]
    assert any(r["route"] == "/v1/kbs/{kb}" and r["status"] == 200 for r in access)
    assert any(r["logger"].startswith("uvicorn") for r in records)  # uvicorn's own, as JSON

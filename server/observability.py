"""Operations: Prometheus metrics at `/metrics` and structured (JSON) logs.

Metrics live in one module-level registry so that the service, the surrogate engine and the
middleware all count into the same series, however many apps a process creates (tests do).
Every name starts with `cpkb_`. Routes are labelled by their template (`/v1/kbs/{kb}/points`),
never by the concrete path, so that the number of series stays bounded; `_created` series are
off, since they double the series count and say only when the process started.

Suggest latency has two sources: the service times the suggests it answers, and planners that
suggest in their own process (the default) may report each local suggestion's seconds in a
point's `source.local_suggest_s`, which is counted once, when the post stores new points.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from fastapi import FastAPI
from fastapi.responses import Response
from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Histogram,
    disable_created_metrics,
    generate_latest,
)
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector
from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

disable_created_metrics()
REGISTRY = CollectorRegistry(auto_describe=True)

# Latency buckets in seconds: from a cached read (~1 ms) to a slow cold fit on a busy machine.
_LATENCY_BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)
_FIT_BUCKETS = (0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0)

HTTP_REQUESTS = Counter(
    "cpkb_http_requests",
    "HTTP requests answered, by method, route template and status code.",
    ("method", "route", "status"),
    registry=REGISTRY,
)
HTTP_LATENCY = Histogram(
    "cpkb_http_request_duration_seconds",
    "Time to answer an HTTP request, by method and route template.",
    ("method", "route"),
    buckets=_LATENCY_BUCKETS,
    registry=REGISTRY,
)
SUGGEST_LATENCY = Histogram(
    "cpkb_suggest_duration_seconds",
    "Time to answer a suggest request (MPF acquisition), successful answers only.",
    buckets=_LATENCY_BUCKETS,
    registry=REGISTRY,
)
PLANNER_SUGGEST_LATENCY = Histogram(
    "cpkb_planner_suggest_duration_seconds",
    "Time a planner took for one suggestion in its own process, as it reported it with its "
    "points (source.local_suggest_s).",
    buckets=_LATENCY_BUCKETS,
    registry=REGISTRY,
)
POINTS_INGESTED = Counter(
    "cpkb_points_ingested",
    "CP points stored (repeated idempotency keys are not counted), by knowledge base.",
    ("kb",),
    registry=REGISTRY,
)
TYPES_CREATED = Counter(
    "cpkb_types_created",
    "CP types created by a points post, by knowledge base.",
    ("kb",),
    registry=REGISTRY,
)
FITS = Counter(
    "cpkb_surrogate_fits",
    "Surrogate fits finished, by outcome (ok or error).",
    ("outcome",),
    registry=REGISTRY,
)
FIT_DURATION = Histogram(
    "cpkb_surrogate_fit_duration_seconds",
    "Wall time of one surrogate fit.",
    buckets=_FIT_BUCKETS,
    registry=REGISTRY,
)
FIT_POINTS = Histogram(
    "cpkb_surrogate_fit_points",
    "Points a surrogate fit was trained on.",
    buckets=(4, 10, 30, 100, 300, 1000, 3000, 10000, 30000),
    registry=REGISTRY,
)

FITS_ADOPTED = Counter(
    "cpkb_surrogate_fits_adopted",
    "Fits loaded from the database (another replica's, or an earlier run's) instead of fitted.",
    registry=REGISTRY,
)

UNMATCHED_ROUTE = "<unmatched>"
REPORTED_SUGGEST_KEY = "local_suggest_s"
# A reported value outside this range, or past this many in one point, is not a timing.
MAX_REPORTED_SUGGEST_S = 3600.0
MAX_REPORTED_SUGGESTS = 256
_access_log = logging.getLogger("cpkb.access")


def record_points_ingested(kb: str, n_new: int, n_new_types: int = 0) -> None:
    """Called by the service after a points post commits: `n_new` points actually stored."""
    if n_new > 0:
        POINTS_INGESTED.labels(kb=kb).inc(n_new)
    if n_new_types > 0:
        TYPES_CREATED.labels(kb=kb).inc(n_new_types)


def record_planner_suggests(sources: Iterable[Mapping[str, Any] | None]) -> int:
    """Observe the local suggest timings planners reported in their points' sources; called
    only for a post that stored new points, so that a retried batch is not counted twice.
    Returns how many were observed."""
    observed = 0
    for source in sources:
        values = (source or {}).get(REPORTED_SUGGEST_KEY)
        if not isinstance(values, list):
            continue
        for value in values[:MAX_REPORTED_SUGGESTS]:
            if isinstance(value, bool) or not isinstance(value, int | float):
                continue
            if 0.0 <= value <= MAX_REPORTED_SUGGEST_S:
                PLANNER_SUGGEST_LATENCY.observe(float(value))
                observed += 1
    return observed


def record_fit(seconds: float, n_points: int, ok: bool = True) -> None:
    """Called by the surrogate engine after each fit (cold or warm)."""
    FITS.labels(outcome="ok" if ok else "error").inc()
    if ok:
        FIT_DURATION.observe(seconds)
        FIT_POINTS.observe(n_points)


def record_fit_adopted() -> None:
    """Called by the surrogate engine when it serves a stored fit instead of fitting."""
    FITS_ADOPTED.inc()


class _StoreCollector(Collector):
    """Scrape-time gauges read from the store: types and points per knowledge base.

    `read` returns rows of (kb name, number of types, number of points); it is the service's
    own listing, so the gauges agree with `GET /v1/kbs`.
    """

    def __init__(self, read: Callable[[], Iterable[tuple[str, int, int]]]) -> None:
        self._read = read

    def collect(self) -> Iterable[GaugeMetricFamily]:
        types = GaugeMetricFamily(
            "cpkb_active_types", "CP types stored, by knowledge base.", labels=["kb"]
        )
        points = GaugeMetricFamily(
            "cpkb_points_stored", "CP points stored, by knowledge base.", labels=["kb"]
        )
        try:
            rows = list(self._read())
        except Exception:  # a scrape must not fail because the database is briefly away
            logging.getLogger("cpkb.metrics").exception("reading store gauges failed")
            rows = []
        for kb, n_types, n_points in rows:
            types.add_metric([kb], n_types)
            points.add_metric([kb], n_points)
        yield types
        yield points

    def describe(self) -> Iterable[GaugeMetricFamily]:
        return []


def set_store_reader(read: Callable[[], Iterable[tuple[str, int, int]]]) -> None:
    """Point the store gauges at the app's database (the latest app created wins)."""
    _register("store", _StoreCollector(read))


class _EngineCollector(Collector):
    """Scrape-time gauges of the surrogate engine (`read` gives it, or None when surrogates
    are off): the fit backlog and how far the served models lag behind the stored points."""

    def __init__(self, read: Callable[[], Any]) -> None:
        self._read = read

    def collect(self) -> Iterable[GaugeMetricFamily]:
        backlog = GaugeMetricFamily(
            "cpkb_surrogate_fit_backlog",
            "CP types queued for a surrogate fit or being fitted, by knowledge base.",
            labels=["kb"],
        )
        unfitted = GaugeMetricFamily(
            "cpkb_surrogate_unfitted_points",
            "Points of loaded types that their served model was not fitted on (they are weighed "
            "in until the next fit lands), by knowledge base.",
            labels=["kb"],
        )
        age = GaugeMetricFamily(
            "cpkb_surrogate_stale_model_age_seconds",
            "Age of the latest fit of the stalest type with unfitted points (0: none lags), by "
            "knowledge base.",
            labels=["kb"],
        )
        engine = self._read()
        for kb, gauge in sorted((engine.gauges() if engine is not None else {}).items()):
            backlog.add_metric([kb], gauge.backlog)
            unfitted.add_metric([kb], gauge.unfitted_points)
            age.add_metric([kb], gauge.stale_model_age_s)
        yield backlog
        yield unfitted
        yield age

    def describe(self) -> Iterable[GaugeMetricFamily]:
        return []


_collectors: dict[str, Collector] = {}


def _register(name: str, collector: Collector) -> None:
    """Register `collector` under `name`, replacing the one an earlier app registered."""
    old = _collectors.pop(name, None)
    if old is not None:
        REGISTRY.unregister(old)
    _collectors[name] = collector
    REGISTRY.register(collector)


def route_template(scope: Scope, routes: Sequence[BaseRoute] = ()) -> str:
    """The matched route's path template; for an answer given before routing (a 413) or by a
    plain Starlette route (`/docs`), the template of the first of `routes` the request matches;
    else a fixed label for paths no route matches."""
    path = getattr(scope.get("route"), "path", None)
    if isinstance(path, str):
        return path
    return _match_template({**scope, "root_path": ""}, routes) or UNMATCHED_ROUTE


def _match_template(scope: Scope, routes: Sequence[BaseRoute]) -> str | None:
    """The template of the route `scope` fully matches, else of one whose path matches with
    another method."""
    full, partial = _matches(scope, routes)
    return full or partial


def _matches(scope: Scope, routes: Sequence[BaseRoute]) -> tuple[str | None, str | None]:
    """(first full match, first partial match), into included routers: FastAPI keeps an
    inclusion as one route holding the router, whose routes' paths carry its prefix."""
    partial = None
    for route in routes:
        inner = getattr(route, "original_router", None)
        if inner is not None:
            full, inner_partial = _matches(scope, inner.routes)
        else:
            match, _ = route.matches(scope)
            path = getattr(route, "path", None)
            if not isinstance(path, str) or match is Match.NONE:
                continue
            full, inner_partial = (path, None) if match is Match.FULL else (None, path)
        if full is not None:
            return full, partial
        partial = partial or inner_partial
    return None, partial


class MetricsMiddleware:
    """Pure ASGI middleware: counts and times every HTTP request by route template, and writes
    one structured access-log record per request."""

    def __init__(self, app: ASGIApp, routes: Sequence[BaseRoute] = ()) -> None:
        self.app = app
        self.routes = routes  # the app's own list: routes added later are matched too

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        status = 500

        async def send_and_record(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, send_and_record)
        finally:
            elapsed = time.perf_counter() - start
            method = scope.get("method", "")
            route = route_template(scope, self.routes)
            HTTP_REQUESTS.labels(method=method, route=route, status=str(status)).inc()
            HTTP_LATENCY.labels(method=method, route=route).observe(elapsed)
            if route.endswith("/suggest") and status < 400:
                SUGGEST_LATENCY.observe(elapsed)
            _access_log.info(
                "request",
                extra={
                    "method": method,
                    "path": scope.get("path", ""),
                    "route": route,
                    "status": status,
                    "duration_ms": round(elapsed * 1000.0, 3),
                },
            )


def metrics_response() -> Response:
    return Response(generate_latest(REGISTRY), media_type=CONTENT_TYPE_LATEST)


def install_observability(
    app: FastAPI, store_reader: Callable[[], Iterable[tuple[str, int, int]]] | None = None
) -> None:
    """Add `/metrics` and the timing middleware to `app`. The store gauges read `store_reader`,
    by default the service's own knowledge-base listing over `app.state.store`."""
    app.add_middleware(MetricsMiddleware, routes=app.router.routes)
    app.add_api_route(
        "/metrics",
        metrics_response,
        methods=["GET"],
        include_in_schema=False,
        response_class=Response,
    )
    if store_reader is None and getattr(app.state, "store", None) is not None:
        store_reader = _kb_listing(app.state.store)
    if store_reader is not None:
        set_store_reader(store_reader)
    # The engine is installed after this (INSTALLERS' order) and may be off: read it per scrape.
    _register("engine", _EngineCollector(lambda: getattr(app.state, "surrogates", None)))


def _kb_listing(store: Any) -> Callable[[], list[tuple[str, int, int]]]:
    from server.services.kbs import list_kbs

    def read() -> list[tuple[str, int, int]]:
        return [(kb.name, kb.n_types, kb.n_points) for kb in list_kbs(store)]

    return read


# Attributes every LogRecord has; anything else on a record came from `extra=` and is logged.
_RECORD_FIELDS = frozenset(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {
    "message",
    "asctime",
    "taskName",
    "color_message",  # uvicorn's message again, with terminal colour codes
}


class JsonFormatter(logging.Formatter):
    """One JSON object per line: time, level, logger, message, and every `extra=` field."""

    def format(self, record: logging.LogRecord) -> str:
        entry: dict[str, Any] = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        for key, value in vars(record).items():
            if key not in _RECORD_FIELDS and not key.startswith("_"):
                entry[key] = value
        if record.exc_info:
            entry["exception"] = self.formatException(record.exc_info)
        return json.dumps(entry, default=str)


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever `sys.stderr` is at the time of the record (test runners swap it)."""

    def __init__(self) -> None:
        super().__init__()

    @property
    def stream(self) -> Any:
        return sys.stderr

    @stream.setter
    def stream(self, _value: Any) -> None:
        """The stream is always the current stderr; the base class's assignment is ignored."""


def configure_json_logging(level: str | int = "INFO") -> None:
    """Send every log record (the service's, uvicorn's with `log_config=None`) to stderr as JSON
    lines. Called once by the serving command; idempotent."""
    root = logging.getLogger()
    root.setLevel(level if isinstance(level, int) else level.upper())
    if not any(isinstance(h, _StderrHandler) for h in root.handlers):
        handler = _StderrHandler()
        handler.setFormatter(JsonFormatter())
        root.addHandler(handler)

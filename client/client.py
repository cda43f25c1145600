"""A typed synchronous client for the knowledge-base service (wire contract v1).

Every call has a timeout; idempotent calls are retried with exponential backoff and jitter on
connection errors and 5xx answers. Once the client has reached the server, connection errors
are retried for at least `reconnect_for` seconds, so a long planner run waits out a server
restart; a server never reached (a wrong URL) still fails after `retries`. Point and binding posts
are made idempotent by a key on each (generated when the caller gives none), so a retry after a
lost answer never stores twice; a create or delete of a knowledge base sent again takes the
409 or 404 its own first try caused as success.
4xx answers raise the matching `client.errors` class carrying the server's detail.

`base_url` may name several replicas of one service (`"http://a:8000,http://b:8000"`, or a
list): a connection error or a 503 moves the client on to the next one at once, and a pause
comes only after every replica was tried. The keys make a post re-sent to another replica as
safe as one re-sent to the same.
"""

from __future__ import annotations

import random
import ssl
import time
import uuid
from collections.abc import Iterable, Iterator, Mapping
from functools import cache
from pathlib import Path
from typing import Any

import httpx
from pydantic import BaseModel, TypeAdapter, ValidationError

from client.errors import CpkbError, NotFound, ServiceUnavailable, error_for
from contract.bindings import BindingIn, BindingOut, BindingsPage
from contract.models import (
    MAX_POINTS_PER_POST,
    Graph,
    Health,
    KnowledgeBase,
    KnowledgeBaseIn,
    MatchIn,
    MatchResult,
    ModelsIn,
    ModelsOut,
    PointIn,
    PointOut,
    PointResult,
    PointsIn,
    PointsOut,
    PointsPage,
    PointsSinceIn,
    PointsSinceOut,
    PredictIn,
    PredictOut,
    SuggestIn,
    SuggestOut,
    TypeDetail,
    TypeSummary,
)

DEFAULT_URL = "http://127.0.0.1:8000"


def split_urls(urls: str | Iterable[str]) -> list[str]:
    """The replica URLs of `"URL1,URL2"` (or of a list), without trailing slashes; ValueError
    for none."""
    parts = urls.split(",") if isinstance(urls, str) else list(urls)
    found = [u.strip().rstrip("/") for u in parts if u.strip()]
    if not found:
        raise ValueError(f"no service URL in {urls!r}")
    return found


@cache
def _tls_context() -> ssl.SSLContext:
    """httpx's default verifying context, built once per process: building it reads the whole
    CA bundle, and a planner opens a client per run."""
    return httpx.create_ssl_context()


class CpkbClient:
    """Talks to one service at `base_url` (one URL, or its replicas' URLs: see the module's
    docstring); use as a context manager or call `close()`."""

    def __init__(
        self,
        base_url: str | Iterable[str] = DEFAULT_URL,
        *,
        timeout: float = 30.0,
        retries: int = 5,
        backoff: float = 0.2,
        max_backoff: float = 5.0,
        reconnect_for: float = 90.0,
        token: str | None = None,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.urls = split_urls(base_url)
        self._current = 0
        self.retries = retries
        self.backoff = backoff
        self.max_backoff = max_backoff
        self.reconnect_for = reconnect_for
        self._reached = False
        self._jitter = random.Random()
        self._http = httpx.Client(
            timeout=timeout,
            headers=headers,
            transport=transport,
            verify=_tls_context(),
        )

    @property
    def base_url(self) -> str:
        """The replica the next call goes to."""
        return self.urls[self._current]

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> CpkbClient:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    # -- transport -------------------------------------------------------------------------

    def _pause(self, attempt: int, response: httpx.Response | None = None) -> None:
        delay = min(self.backoff * 2**attempt, self.max_backoff)
        if response is not None and response.headers.get("Retry-After", "").isdigit():
            delay = max(delay, min(float(response.headers["Retry-After"]), self.max_backoff))
        time.sleep(delay * (0.5 + self._jitter.random()))

    def request(
        self,
        method: str,
        path: str,
        *,
        json: Any = None,
        params: Mapping[str, Any] | None = None,
        retry: bool = True,
    ) -> httpx.Response:
        """One call with retries (when `retry`) on connection errors and 5xx; raises on 4xx.
        With several replicas, each try that meets a connection error or a 503 goes on to the
        next replica; the pause between tries comes once a round has been through them all."""
        response, _ = self._exchange(method, path, json=json, params=params, retry=retry)
        if response.is_error:
            raise error_for(response)
        return response

    def _exchange(
        self,
        method: str,
        path: str,
        *,
        json: Any = None,
        params: Mapping[str, Any] | None = None,
        retry: bool = True,
    ) -> tuple[httpx.Response, bool]:
        """The final answer of `request` (an error answer too), and whether the call was sent
        more than once: an earlier try may have acted although its answer was lost."""
        attempts = (1 + (self.retries if retry else 0)) * len(self.urls)
        reconnect_until = time.monotonic() + (self.reconnect_for if retry else 0.0)
        attempt = 0
        while True:
            attempt += 1
            more = attempt < attempts
            url = self.base_url + path
            try:
                response = self._http.request(method, url, json=json, params=params)
            except httpx.TransportError as exc:
                restarting = self._reached and time.monotonic() < reconnect_until
                if not (more or restarting):
                    raise ServiceUnavailable(
                        f"cannot reach the knowledge base at {self._where()}: "
                        f"{type(exc).__name__}: {exc}"
                    ) from exc
                # While waiting out a restart, poll every ~1.6 s rather than backing off further.
                self._next_replica(attempt, 3 if not more else None)
                continue
            self._reached = True
            if response.status_code >= 500 and more:
                if response.status_code == 503:
                    self._next_replica(attempt, None, response)
                else:
                    self._pause(self._round(attempt), response)
                continue
            return response, attempt > 1

    def _round(self, attempt: int) -> int:
        return (attempt - 1) // len(self.urls)

    def _next_replica(
        self, attempt: int, level: int | None, response: httpx.Response | None = None
    ) -> None:
        """Move on to the next replica; pause (at backoff `level`, or the round's) only when
        this try ended a round through all of them."""
        self._current = (self._current + 1) % len(self.urls)
        if attempt % len(self.urls) == 0:
            self._pause(self._round(attempt) if level is None else level, response)

    def _where(self) -> str:
        return self.urls[0] if len(self.urls) == 1 else "any of " + ", ".join(self.urls)

    def _call(self, model: Any, method: str, path: str, **kwargs: Any) -> Any:
        response = self.request(method, path, **kwargs)
        try:
            return _adapter(model).validate_python(response.json())
        except (ValueError, ValidationError) as exc:
            # An answer this client cannot read (an older service serving a row it once let
            # in): one line naming the call, not a validation traceback in the caller.
            first = exc.errors()[0] if isinstance(exc, ValidationError) else {"msg": str(exc)}
            where = ".".join(str(p) for p in first.get("loc", ()))
            raise CpkbError(
                f"{method} {path}: the service's answer does not fit the wire contract"
                f" ({where + ': ' if where else ''}{first['msg']})",
                status=response.status_code,
            ) from exc

    @staticmethod
    def _body(model: BaseModel) -> Any:
        return model.model_dump(mode="json", exclude_none=True)

    # -- service and knowledge bases ---------------------------------------------------------

    def health(self) -> Health:
        return self._call(Health, "GET", "/healthz")

    def create_kb(self, name: str, *, exist_ok: bool = False) -> KnowledgeBase:
        """Create a knowledge base; with `exist_ok`, an existing one is returned instead. That
        case asks first, so that a planner's every run does not leave a 409 in the service's
        metrics; a 409 still answers a creation racing another. A 409 to a create sent again
        (the first try's answer was lost, and it may have created the base) is taken as this
        call's own success."""
        body = self._body(KnowledgeBaseIn(name=name))
        if exist_ok:
            try:
                return self.get_kb(name)
            except NotFound:
                pass
        response, resent = self._exchange("POST", "/v1/kbs", json=body)
        if response.status_code == 409 and (exist_ok or resent):
            return self.get_kb(name)
        if response.is_error:
            raise error_for(response)
        return _adapter(KnowledgeBase).validate_python(response.json())

    def get_kb(self, name: str) -> KnowledgeBase:
        return self._call(KnowledgeBase, "GET", f"/v1/kbs/{name}")

    def list_kbs(self) -> list[KnowledgeBase]:
        return self._call(list[KnowledgeBase], "GET", "/v1/kbs")

    def delete_kb(self, name: str) -> None:
        """Delete a knowledge base; a 404 to a delete sent again (the first try's answer was
        lost, and it may have deleted the base) is taken as this call's own success."""
        response, resent = self._exchange("DELETE", f"/v1/kbs/{name}")
        if response.is_error and not (response.status_code == 404 and resent):
            raise error_for(response)

    # -- points ------------------------------------------------------------------------------

    def post_points(
        self,
        kb: str,
        points: Iterable[PointIn | Mapping[str, Any]],
        *,
        batch_size: int = MAX_POINTS_PER_POST,
    ) -> list[PointResult]:
        """Post points in batches (at most 1000 per request); one result per point, in order.

        A point without `key` gets a fresh one, so retries of this call never store twice.
        """
        if not 1 <= batch_size <= MAX_POINTS_PER_POST:
            raise ValueError(f"batch_size must be in [1, {MAX_POINTS_PER_POST}]")
        keyed = [_with_key(p) for p in points]
        results: list[PointResult] = []
        for start in range(0, len(keyed), batch_size):
            body = self._body(PointsIn(points=keyed[start : start + batch_size]))
            out = self._call(PointsOut, "POST", f"/v1/kbs/{kb}/points", json=body)
            results.extend(out.results)
        return results

    def list_points(
        self, kb: str, type_id: str, *, limit: int | None = None, cursor: str | None = None
    ) -> PointsPage:
        params = {k: v for k, v in {"limit": limit, "cursor": cursor}.items() if v is not None}
        return self._call(PointsPage, "GET", f"/v1/kbs/{kb}/types/{type_id}/points", params=params)

    def points_since(
        self,
        kb: str,
        type_ids: Iterable[str],
        after_point_id: int | None = None,
        *,
        exclude_run: str | None = None,
        limit: int = MAX_POINTS_PER_POST,
    ) -> PointsSinceOut:
        """Points of these types stored after the cursor `after_point_id` (None: just the
        cursor to start from), without those of run `exclude_run`."""
        request = PointsSinceIn(
            type_ids=list(type_ids),
            after_point_id=after_point_id,
            exclude_run=exclude_run,
            limit=limit,
        )
        body = self._body(request)
        return self._call(PointsSinceOut, "POST", f"/v1/kbs/{kb}/points/since", json=body)

    def add_binding(self, kb: str, binding: BindingIn) -> BindingOut:
        """Store a binding list found for a task. A binding without `key` gets a fresh one, so
        retries of this call never store it twice."""
        if binding.key is None:
            binding = binding.model_copy(update={"key": uuid.uuid4().hex})
        return self._call(BindingOut, "POST", f"/v1/kbs/{kb}/bindings", json=self._body(binding))

    def bindings(
        self,
        kb: str,
        *,
        skeleton: str | None = None,
        task: str | None = None,
        after: int | None = None,
        exclude_run: str | None = None,
        limit: int | None = None,
    ) -> BindingsPage:
        """Found bindings after the cursor `after`, oldest first."""
        asked = {
            "skeleton": skeleton,
            "task": task,
            "after": after,
            "exclude_run": exclude_run,
            "limit": limit,
        }
        params = {k: v for k, v in asked.items() if v is not None}
        return self._call(BindingsPage, "GET", f"/v1/kbs/{kb}/bindings", params=params)

    def iter_points(self, kb: str, type_id: str, *, page_size: int = 1000) -> Iterator[PointOut]:
        """Every point of a type in insertion order, fetched page by page."""
        cursor: str | None = None
        while True:
            page = self.list_points(kb, type_id, limit=page_size, cursor=cursor)
            yield from page.points
            if page.next_cursor is None:
                return
            cursor = page.next_cursor

    def export_csv(self, kb: str, type_id: str, path: str | Path | None = None) -> str:
        """The type's table as CSV text (also written to `path` when given)."""
        response = self.request("GET", f"/v1/kbs/{kb}/types/{type_id}/points.csv")
        if path is not None:
            Path(path).write_bytes(response.content)
        return response.text

    # -- types -------------------------------------------------------------------------------

    def match_types(
        self, kb: str, graphs: Iterable[Graph | Mapping[str, Any]]
    ) -> list[MatchResult]:
        body = self._body(MatchIn(graphs=[Graph.model_validate(g) for g in graphs]))
        return self._call(list[MatchResult], "POST", f"/v1/kbs/{kb}/types/match", json=body)

    def list_types(self, kb: str) -> list[TypeSummary]:
        return self._call(list[TypeSummary], "GET", f"/v1/kbs/{kb}/types")

    def get_type(self, kb: str, type_id: str) -> TypeDetail:
        return self._call(TypeDetail, "GET", f"/v1/kbs/{kb}/types/{type_id}")

    # -- surrogates ---------------------------------------------------------------------------
    def suggest(self, kb: str, request: SuggestIn | Mapping[str, Any]) -> SuggestOut:
        """The MPF suggestion for a search space (see SuggestIn); safe to retry (reads only)."""
        model = request if isinstance(request, SuggestIn) else SuggestIn.model_validate(request)
        return self._call(SuggestOut, "POST", f"/v1/kbs/{kb}/suggest", json=self._body(model))

    def models(
        self, kb: str, type_ids: Iterable[str], known: Mapping[str, str] | None = None
    ) -> ModelsOut:
        """The current predictors of these types (minus those still at a `known` version)."""
        body = self._body(ModelsIn(type_ids=list(type_ids), known=dict(known or {})))
        return self._call(ModelsOut, "POST", f"/v1/kbs/{kb}/models", json=body)

    def predict(self, kb: str, type_id: str, xs: Iterable[Mapping[str, Any]]) -> list[float]:
        """P(feasible) of each x (decision label -> value) under the type's surrogate."""
        body = self._body(PredictIn(x=[dict(x) for x in xs]))
        path = f"/v1/kbs/{kb}/types/{type_id}/predict"
        return self._call(PredictOut, "POST", path, json=body).p_feasible


@cache
def _adapter(model: Any) -> TypeAdapter[Any]:
    return TypeAdapter(model)


def _with_key(point: PointIn | Mapping[str, Any]) -> PointIn:
    model = point if isinstance(point, PointIn) else PointIn.model_validate(point)
    return model if model.key is not None else model.model_copy(update={"key": uuid.uuid4().hex})

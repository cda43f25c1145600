"""Client-side errors, one class per kind of answer a caller may want to handle.

Every error carries the HTTP `status` (None when the server was never reached) and the
server's `detail`, so that `str(error)` reads like the server's own explanation.
"""

from __future__ import annotations

from typing import Any

import httpx


class CpkbError(Exception):
    """Any failed call to the knowledge base."""

    def __init__(self, message: str, *, status: int | None = None, detail: Any = None) -> None:
        super().__init__(message)
        self.status = status
        self.detail = detail if detail is not None else message


class BadRequest(CpkbError):
    """400 / 413 / 422: the request was invalid; `detail` names the field."""


class Unauthorized(CpkbError):
    """401 / 403: a token is missing or wrong."""


class NotFound(CpkbError):
    """404: no such knowledge base or type."""


class Conflict(CpkbError):
    """409: e.g. a knowledge base that exists, or a graph that clashes with a stored type."""


class ServerError(CpkbError):
    """5xx after every retry."""


class ServiceUnavailable(CpkbError):
    """The service could not be reached (connection refused, timeout) after every retry."""


_BY_STATUS: dict[int, type[CpkbError]] = {
    400: BadRequest,
    401: Unauthorized,
    403: Unauthorized,
    404: NotFound,
    409: Conflict,
    413: BadRequest,
    422: BadRequest,
}


def _readable(detail: Any) -> str:
    """FastAPI's validation details (a list of {loc, msg}) as one line."""
    if isinstance(detail, list):
        parts = []
        for item in detail:
            if isinstance(item, dict) and "msg" in item:
                loc = ".".join(str(p) for p in item.get("loc", ()) if p != "body")
                parts.append(f"{loc}: {item['msg']}" if loc else str(item["msg"]))
            else:
                parts.append(str(item))
        return "; ".join(parts)
    return str(detail)


def error_for(response: httpx.Response) -> CpkbError:
    """The exception for an error response, with the server's detail."""
    try:
        detail = response.json().get("detail", response.text)
    except ValueError:
        detail = response.text or response.reason_phrase
    status = response.status_code
    cls = _BY_STATUS.get(status)
    if cls is None:
        cls = ServerError if status >= 500 else BadRequest
    if status == 503:
        cls = ServiceUnavailable
    message = f"{status} {response.request.method} {response.request.url.path}: {_readable(detail)}"
    return cls(message, status=status, detail=detail)

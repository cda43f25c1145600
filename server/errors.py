"""Errors the services raise, each with the HTTP status it maps to; handlers turn them into
`{"detail": ...}` answers, so that no bad input or busy database ever becomes a 500."""

from __future__ import annotations

import logging
import math
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, IntegrityError, OperationalError, SQLAlchemyError

log = logging.getLogger("cpkb.server")
FOREIGN_KEY_VIOLATION = "23503"  # PostgreSQL's SQLSTATE
MAX_ECHOED_INPUT = 200  # characters of a rejected string a 422 answer repeats


class ServiceError(Exception):
    """Base of the errors a client can act on; `status` is the HTTP status."""

    status = 400

    def __init__(self, detail: str) -> None:
        super().__init__(detail)
        self.detail = detail


class InvalidInput(ServiceError):
    status = 422


class NotFound(ServiceError):
    status = 404


class Conflict(ServiceError):
    status = 409


class TooLarge(ServiceError):
    """A request asks for more work than the service does for one (a setting says how much)."""

    status = 413


class Unavailable(ServiceError):
    """The database is busy or unreachable: retry later (answered with Retry-After)."""

    status = 503


def _first_line(exc: SQLAlchemyError) -> str:
    orig = getattr(exc, "orig", None)
    text = str(orig if orig is not None else exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _refers_to_deleted_row(exc: IntegrityError) -> bool:
    """A foreign key violation: the write refers to a knowledge base or type that a concurrent
    DELETE removed after this transaction looked it up (PostgreSQL's read committed)."""
    orig = getattr(exc, "orig", None)
    sqlstate = getattr(orig, "sqlstate", None)
    return sqlstate == FOREIGN_KEY_VIOLATION or "FOREIGN KEY constraint failed" in str(orig)


def map_db_error(exc: SQLAlchemyError) -> ServiceError:
    """A database error as a client-facing error: a vanished parent -> 404, any other
    constraint -> 409, bad value -> 422, anything operational (locked, timeout, connection
    lost) -> 503."""
    if isinstance(exc, IntegrityError) and _refers_to_deleted_row(exc):
        return NotFound("the knowledge base or type this write refers to was deleted meanwhile")
    if isinstance(exc, IntegrityError):
        return Conflict(f"the write conflicts with stored data: {_first_line(exc)}")
    if isinstance(exc, DataError):
        return InvalidInput(f"a value does not fit the database: {_first_line(exc)}")
    if isinstance(exc, OperationalError):
        log.warning("database unavailable: %s", _first_line(exc))
        return Unavailable(f"database busy or unreachable, retry: {_first_line(exc)}")
    log.warning("database error: %s", _first_line(exc))
    return Unavailable(f"database error, retry: {_first_line(exc)}")


def _answer(exc: ServiceError) -> JSONResponse:
    headers = {"Retry-After": "1"} if isinstance(exc, Unavailable) else None
    return JSONResponse({"detail": _encodable(exc.detail)}, status_code=exc.status, headers=headers)


def install_error_handlers(app: FastAPI) -> None:
    async def service_error(_: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, ServiceError)
        return _answer(exc)

    async def database_error(_: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, SQLAlchemyError)
        return _answer(map_db_error(exc))

    async def validation_error(_: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        errors = [_without_bulky_input(error) for error in exc.errors()]
        detail = _encodable(_finite(jsonable_encoder(errors)))
        return JSONResponse({"detail": detail}, status_code=422)

    app.add_exception_handler(ServiceError, service_error)
    app.add_exception_handler(SQLAlchemyError, database_error)
    app.add_exception_handler(RequestValidationError, validation_error)


def _without_bulky_input(error: dict[str, Any]) -> dict[str, Any]:
    """A validation error echoes the rejected value only when it is a short scalar: echoing a
    whole rejected body (megabytes, or nested deeper than the encoder goes) helps nobody."""
    value = error.get("input")
    short = value is None or isinstance(value, bool | int | float)
    short = short or (isinstance(value, str) and len(value) <= MAX_ECHOED_INPUT)
    return error if short else {k: v for k, v in error.items() if k != "input"}


def _encodable(value: Any) -> Any:
    """Strings that UTF-8 can encode: a lone surrogate (JSON's "\\ud800") in a key or value
    that an answer names is sent as its escape, not as an error while answering."""
    if isinstance(value, str):
        if value.isascii():
            return value
        return value.encode("utf-8", "backslashreplace").decode("utf-8")
    if isinstance(value, dict):
        return {_encodable(k): _encodable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_encodable(v) for v in value]
    return value


def _finite(value: Any) -> Any:
    """FastAPI echoes the rejected input; a NaN or infinity in it (json.loads accepts them)
    would make the answer itself unencodable, so they are echoed as strings."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value

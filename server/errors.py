"""Errors the services raise, each with the HTTP status it maps to; handlers turn them into
`{"detail": ...}` answers, so that no bad input or busy database ever becomes a 500."""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, IntegrityError, OperationalError, SQLAlchemyError

log = logging.getLogger("cpkb.server")


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


class Unavailable(ServiceError):
    """The database is busy or unreachable: retry later (answered with Retry-After)."""

    status = 503


def _first_line(exc: SQLAlchemyError) -> str:
    orig = getattr(exc, "orig", None)
    text = str(orig if orig is not None else exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def map_db_error(exc: SQLAlchemyError) -> ServiceError:
    """A database error as a client-facing error: constraint -> 409, bad value -> 422,
    anything operational (locked, timeout, connection lost) -> 503."""
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
    return JSONResponse({"detail": exc.detail}, status_code=exc.status, headers=headers)


def install_error_handlers(app: FastAPI) -> None:
    async def service_error(_: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, ServiceError)
        return _answer(exc)

    async def database_error(_: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, SQLAlchemyError)
        return _answer(map_db_error(exc))

    app.add_exception_handler(ServiceError, service_error)
    app.add_exception_handler(SQLAlchemyError, database_error)

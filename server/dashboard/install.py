"""What the dashboard adds to the app beyond its routes: compressed answers, and errors on its
HTML pages answered as an HTML page (a person reads them) while the API keeps its JSON."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse
from fastapi.routing import APIRoute
from starlette.middleware.gzip import GZipMiddleware
from starlette.responses import Response

from server.dashboard.routes import templates
from server.errors import ServiceError

# The app's JSON error handlers, which install_error_handlers registers as coroutines.
Handler = Callable[[Request, Exception], Awaitable[Response]]
GZIP_MIN_BYTES = 1000  # smaller answers gain less than the header costs
# zlib's default rather than level 9: less CPU on the API docs' 1.5 MB script for 0.3 % more bytes.
GZIP_LEVEL = 6
TITLES = {404: "Not found", 422: "Bad request"}


def is_html_page(request: Request) -> bool:
    route = request.scope.get("route")
    return isinstance(route, APIRoute) and route.response_class is HTMLResponse


def error_page(request: Request, status: int, message: str) -> Response:
    context = {"title": TITLES.get(status, "Error"), "message": message}
    return templates.TemplateResponse(request, "error.html", context, status_code=status)


def _validation_message(exc: RequestValidationError) -> str:
    parts = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error.get("loc", ())[1:]) or "request"
        parts.append(f"{where}: {error.get('msg', 'invalid')}")
    return "; ".join(parts)


def install_dashboard(app: FastAPI) -> None:
    app.add_middleware(GZipMiddleware, minimum_size=GZIP_MIN_BYTES, compresslevel=GZIP_LEVEL)
    as_json_service: Handler = app.exception_handlers[ServiceError]  # type: ignore[assignment]
    as_json_validation: Handler = app.exception_handlers[RequestValidationError]  # type: ignore[assignment]

    async def service_error(request: Request, exc: Exception) -> Any:
        if is_html_page(request) and isinstance(exc, ServiceError):
            return error_page(request, exc.status, exc.detail)
        return await as_json_service(request, exc)

    async def validation_error(request: Request, exc: Exception) -> Any:
        if is_html_page(request) and isinstance(exc, RequestValidationError):
            return error_page(request, 422, _validation_message(exc))
        return await as_json_validation(request, exc)

    app.add_exception_handler(ServiceError, service_error)
    app.add_exception_handler(RequestValidationError, validation_error)

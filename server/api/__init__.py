"""The routers of the service, listed once: the app includes them in this order.

To add an endpoint family, write a router module and add it to ROUTERS; to wire hooks or
state at start (see server.hooks), add an installer `fn(app) -> None` to INSTALLERS.
"""

from __future__ import annotations

from collections.abc import Callable

from fastapi import APIRouter, FastAPI

from server import dashboard
from server.api import bindings, health, kbs, points, types
from server.api import surrogates as surrogate_routes
from server.observability import install_observability
from server.surrogates import install as install_surrogates

ROUTERS: list[APIRouter] = [
    health.router,
    kbs.router,
    types.router,
    points.router,
    bindings.router,
    surrogate_routes.router,
    dashboard.router,
]
INSTALLERS: list[Callable[[FastAPI], None]] = [
    install_observability,
    install_surrogates,
    dashboard.install_dashboard,
]

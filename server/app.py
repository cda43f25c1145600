"""The FastAPI application: `create_app(settings)` migrates the database, makes sure the
`default` knowledge base exists, and wires routers, error handlers, security and hooks."""

from __future__ import annotations

import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from anyio import CapacityLimiter
from fastapi import Depends, FastAPI
from fastapi_offline import FastAPIOffline

from server import __version__
from server.api import INSTALLERS, ROUTERS
from server.api.query import known_query_only
from server.db import Store
from server.errors import install_error_handlers
from server.hooks import ServiceHooks
from server.schema import prepare_database
from server.security import DOCS_ASSETS, bearer_scheme, install_security
from server.settings import Settings


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    store = Store.from_url(settings.database_url, settings.engine_options())
    prepare_database(store)
    hooks = ServiceHooks()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # The health probe's own threads (server.api.health), made in the server's event loop.
        app.state.probe_lane = CapacityLimiter(2)
        # CPU-heavy requests anyone may send (server.api.deps.in_heavy_lane): one per core the
        # service may run on, two at least (torch releases the GIL; hashing does not).
        app.state.heavy_lane = CapacityLimiter(max(2, len(os.sched_getaffinity(0))))
        for start in hooks.on_startup:
            start()
        try:
            yield
        finally:
            for stop in reversed(hooks.on_shutdown):
                stop()
            store.dispose()

    # The API docs' scripts and styles come from the installed fastapi-offline package, not a
    # CDN, so that /docs and /redoc work on a machine without internet.
    app = FastAPIOffline(
        static_url=DOCS_ASSETS,
        title="cpkb",
        version=__version__,
        summary="Constraint-primitive knowledge base for task and motion planning",
        lifespan=lifespan,
        dependencies=[Depends(bearer_scheme), Depends(known_query_only)],
    )
    app.state.settings = settings
    app.state.store = store
    app.state.hooks = hooks
    install_error_handlers(app)
    install_security(app, settings)
    for router in ROUTERS:
        app.include_router(router)
    for install in INSTALLERS:
        install(app)
    return app

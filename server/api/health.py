"""Liveness and readiness: answers only when the database answers.

The probe runs on a connection of its own (`Store.ping`) and in a thread lane of its own, so
that a health check never queues behind requests that hold the pool's connections or the
worker threads (posts waiting on a lock, heavy matches): a load balancer asking a busy but
working replica hears that it works.
"""

from __future__ import annotations

from anyio import to_thread
from fastapi import APIRouter, Request

from contract.models import Health
from server import __version__
from server.api.responses import errors
from server.db import Store

router = APIRouter(tags=["health"], responses=errors(503))


@router.get("/healthz")
@router.head("/healthz", include_in_schema=False)  # load balancers' probes; answers as GET
async def healthz(request: Request) -> Health:
    """Ok when the database answers; the service's version and database dialect."""
    # No sync dependency (FastAPI would run it on the shared worker threads).
    store: Store = request.app.state.store
    await to_thread.run_sync(store.ping, limiter=request.app.state.probe_lane)
    return Health(status="ok", version=__version__, database=store.dialect)

"""Liveness and readiness: answers only when the database answers."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from contract.models import Health
from server import __version__
from server.api.deps import StoreDep
from server.api.responses import errors

router = APIRouter(tags=["health"], responses=errors(503))


@router.get("/healthz")
def healthz(store: StoreDep) -> Health:
    """Ok when the database answers; the service's version and database dialect."""
    with store.transaction() as session:
        session.execute(text("SELECT 1"))
    return Health(status="ok", version=__version__, database=store.dialect)

"""Found bindings: a planner stores the one it found; planners of the same task read them."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status

from contract.bindings import MAX_BINDINGS_PAGE, BindingIn, BindingOut, BindingsPage
from contract.models import MAX_LABEL, MAX_SEED
from server.api.deps import StoreDep
from server.api.responses import BODY, IN_KB, INVALID
from server.services import bindings

router = APIRouter(prefix="/v1/kbs/{kb}/bindings", tags=["bindings"], responses=IN_KB)


@router.post("", status_code=status.HTTP_201_CREATED, responses=BODY)
def add_binding(kb: str, body: BindingIn, store: StoreDep) -> BindingOut:
    """Store a binding list a planner found for its task."""
    return bindings.add_binding(store, kb, body)


@router.get("", responses=INVALID)
def list_bindings(
    kb: str,
    store: StoreDep,
    skeleton: Annotated[str | None, Query(max_length=MAX_LABEL)] = None,
    task: Annotated[str | None, Query(max_length=MAX_LABEL)] = None,
    after: Annotated[int | None, Query(ge=0, le=MAX_SEED)] = None,
    exclude_run: Annotated[str | None, Query(max_length=MAX_LABEL)] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_BINDINGS_PAGE)] = MAX_BINDINGS_PAGE,
) -> BindingsPage:
    """Bindings after id `after` (a cursor of an earlier answer), oldest first; of one task's
    skeleton if asked, without one run's."""
    return bindings.list_bindings(
        store, kb, skeleton=skeleton, task=task, after=after, exclude_run=exclude_run, limit=limit
    )

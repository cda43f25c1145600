"""Knowledge bases."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from contract.models import KnowledgeBase, KnowledgeBaseIn
from server.api.deps import HooksDep, StoreDep
from server.api.responses import BODY, COMMON, errors
from server.services import kbs

router = APIRouter(prefix="/v1/kbs", tags=["knowledge bases"], responses=COMMON)


@router.post("", status_code=status.HTTP_201_CREATED, responses=errors(409) | BODY)
def create_kb(body: KnowledgeBaseIn, store: StoreDep) -> KnowledgeBase:
    """Create a knowledge base (409 if the name is taken)."""
    return kbs.create_kb(store, body.name)


@router.get("")
def list_kbs(store: StoreDep) -> list[KnowledgeBase]:
    """Every knowledge base with its type and point counts."""
    return kbs.list_kbs(store)


@router.get("/{kb}", responses=errors(404, 422))
def get_kb(kb: str, store: StoreDep) -> KnowledgeBase:
    """One knowledge base with its type and point counts."""
    return kbs.get_kb(store, kb)


@router.delete("/{kb}", status_code=status.HTTP_204_NO_CONTENT, responses=errors(404, 422))
def delete_kb(kb: str, store: StoreDep, hooks: HooksDep) -> Response:
    """Delete a knowledge base and everything in it; `default` comes back empty."""
    kbs.delete_kb(store, kb)
    hooks.notify_kb_deleted(kb)
    return Response(status_code=status.HTTP_204_NO_CONTENT)

"""CP types: match graphs to types, list them, one type in detail."""

from __future__ import annotations

from fastapi import APIRouter

from contract.models import MatchIn, MatchResult, TypeDetail, TypeSummary
from server.api.deps import HooksDep, StoreDep
from server.api.responses import BODY, IN_KB, INVALID, errors
from server.services import types

router = APIRouter(prefix="/v1/kbs/{kb}/types", tags=["types"], responses=IN_KB)


@router.post("/match", responses=errors(409) | BODY)
def match_types(kb: str, body: MatchIn, store: StoreDep) -> list[MatchResult]:
    """Type IDs of the graphs and whether this knowledge base knows them; stores nothing."""
    return types.match_types(store, kb, body.graphs)


@router.get("", responses=INVALID)
def list_types(kb: str, store: StoreDep) -> list[TypeSummary]:
    """The knowledge base's types, most recently updated first."""
    return types.list_types(store, kb)


@router.get("/{type_id}", responses=INVALID)
def get_type(kb: str, type_id: str, store: StoreDep, hooks: HooksDep) -> TypeDetail:
    """The type: canonical graph, decision space, counts, and the surrogate's state."""
    detail = types.get_type(store, kb, type_id)
    detail.surrogate = hooks.surrogate(kb, type_id)
    return detail

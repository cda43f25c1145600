"""CP types: match graphs to types, list them, one type in detail."""

from __future__ import annotations

from fastapi import APIRouter, Request

from contract.models import MatchIn, MatchResult, TypeDetail, TypeSummary
from server.api.deps import HooksDep, SettingsDep, StoreDep, in_heavy_lane
from server.api.responses import BODY, IN_KB, INVALID, errors
from server.services import types

router = APIRouter(prefix="/v1/kbs/{kb}/types", tags=["types"], responses=IN_KB)


@router.post("/match", responses=errors(409) | BODY)
async def match_types(
    kb: str, body: MatchIn, store: StoreDep, settings: SettingsDep, request: Request
) -> list[MatchResult]:
    """Type IDs of the graphs and whether this knowledge base knows them; stores nothing.
    413 when the distinct graphs hold more than CPKB_MAX_REQUEST_GRAPH_NODES nodes in all."""
    max_nodes = settings.max_request_graph_nodes
    return await in_heavy_lane(
        request, types.match_types, store, kb, body.graphs, max_nodes=max_nodes
    )


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

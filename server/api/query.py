"""Query strings are checked whole: a parameter the route does not take is a 422 naming it
(with the ones it does take), never silently ignored, so that a misspelt filter cannot pass
for an answer to it."""

from __future__ import annotations

from fastapi import Request
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute

from server.errors import InvalidInput


def _declared(dependant: Dependant) -> set[str]:
    names = {field.alias for field in dependant.query_params}
    for sub in dependant.dependencies:
        names |= _declared(sub)
    return names


def query_names(route: APIRoute) -> frozenset[str]:
    """Every query parameter the route and its dependencies declare, by the name sent."""
    return frozenset(_declared(route.dependant))


async def known_query_only(request: Request) -> None:
    """An app-wide dependency: refuse query parameters the matched route does not declare
    (async: it does no I/O, so it never waits for a worker thread behind blocked writes)."""
    route = request.scope.get("route")
    if not isinstance(route, APIRoute):
        return
    allowed = query_names(route)
    unknown = sorted(set(request.query_params) - allowed)
    if unknown:
        takes = ", ".join(sorted(allowed)) if allowed else "none"
        raise InvalidInput(
            f"unknown query parameter {', '.join(map(repr, unknown))} (this route takes: {takes})"
        )

"""Request dependencies: the app's Store, hooks and settings."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Annotated, Any, TypeVar

from anyio import to_thread
from fastapi import Depends, Request

from server.db import Store
from server.hooks import ServiceHooks
from server.security import may_write
from server.settings import Settings


def _store(request: Request) -> Store:
    return request.app.state.store


def _hooks(request: Request) -> ServiceHooks:
    return request.app.state.hooks


def _settings(request: Request) -> Settings:
    return request.app.state.settings


StoreDep = Annotated[Store, Depends(_store)]
HooksDep = Annotated[ServiceHooks, Depends(_hooks)]
SettingsDep = Annotated[Settings, Depends(_settings)]
# True when the caller could write (server.security.may_write): a read route that would
# otherwise leave a trace others see (a suggestion recorded as pending) leaves none without.
WriterDep = Annotated[bool, Depends(may_write)]


T = TypeVar("T")


async def in_heavy_lane(request: Request, work: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """Run CPU-heavy `work` on the app's heavy lane: at most one such request per core computes
    at once, so that however many arrive, reads and health checks keep threads and the GIL's
    turns."""
    call = partial(work, *args, **kwargs)
    return await to_thread.run_sync(call, limiter=request.app.state.heavy_lane)

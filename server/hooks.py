"""Extension points of the service, kept on `app.state.hooks` (a `ServiceHooks`).

The surrogate engine plugs in here without the core knowing it:
- `points_added`: callables `(kb, type_ids)` run right after a commit that stored new points,
  on the request's thread: they must only schedule work (a queue put), never fit.
- `surrogate_state`: `(kb, type_id) -> SurrogateState | None`, shown by GET type detail.
- `kb_deleted`: callables `(kb)` run right after a commit that deleted a knowledge base, so
  that one created again under its name starts with nothing cached.
- `on_startup` / `on_shutdown`: callables run by the app's lifespan (start / stop workers).
A hook that raises is logged and ignored: it never fails the request that triggered it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

from contract.models import SurrogateState

log = logging.getLogger("cpkb.server")

PointsAddedHook = Callable[[str, frozenset[str]], None]
SurrogateStateProvider = Callable[[str, str], SurrogateState | None]


@dataclass
class ServiceHooks:
    points_added: list[PointsAddedHook] = field(default_factory=list)
    surrogate_state: SurrogateStateProvider | None = None
    kb_deleted: list[Callable[[str], None]] = field(default_factory=list)
    on_startup: list[Callable[[], None]] = field(default_factory=list)
    on_shutdown: list[Callable[[], None]] = field(default_factory=list)

    def notify_points_added(self, kb: str, type_ids: frozenset[str]) -> None:
        for hook in self.points_added:
            try:
                hook(kb, type_ids)
            except Exception:
                log.exception("points_added hook %r failed", hook)

    def notify_kb_deleted(self, kb: str) -> None:
        for hook in self.kb_deleted:
            try:
                hook(kb)
            except Exception:
                log.exception("kb_deleted hook %r failed", hook)

    def surrogate(self, kb: str, type_id: str) -> SurrogateState | None:
        if self.surrogate_state is None:
            return None
        try:
            return self.surrogate_state(kb, type_id)
        except Exception:
            log.exception("surrogate_state provider failed for %s/%s", kb, type_id)
            return None

"""Scenario knowledge bases on a cpkb service, created and deleted through the typed client."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from client import CpkbClient
    from contract.models import TypeDetail

FIT_WAIT_S = 120.0
SETTLED = frozenset({"ready", "prior", "error"})


@dataclass(frozen=True)
class ServiceKbs:
    """A service at `url`; picklable, so each worker opens its own client."""

    url: str
    token: str | None = None

    def _client(self) -> CpkbClient:  # imported lazily: `cpkb --help` stays fast
        from client import CpkbClient

        return CpkbClient(self.url, token=self.token)

    def create(self, name: str) -> None:
        with self._client() as client:
            client.create_kb(name)

    def delete(self, name: str) -> None:
        with self._client() as client:
            client.delete_kb(name)

    def delete_prefix(self, prefix: str) -> int:
        """Delete every knowledge base whose name starts with `prefix` (runs cut short)."""
        with self._client() as client:
            names = [kb.name for kb in client.list_kbs() if kb.name.startswith(prefix)]
            for name in names:
                client.delete_kb(name)
        return len(names)

    def count_points(self, name: str) -> int:
        """The points `name` holds."""
        with self._client() as client:
            return client.get_kb(name).n_points

    def wait_fitted(self, name: str, timeout: float = FIT_WAIT_S) -> float:
        """Block until every type of `name` has a surrogate fitted on all its points, the state a
        persistent knowledge base reaches between two tasks; returns the seconds waited (at most
        `timeout`: a target never waits longer than that for its predecessors' fits)."""
        started = time.perf_counter()
        with self._client() as client:
            while time.perf_counter() - started < timeout:
                if all(_settled(client.get_type(name, t.type_id)) for t in client.list_types(name)):
                    break
                time.sleep(0.2)
        return time.perf_counter() - started


def _settled(detail: TypeDetail) -> bool:
    state = detail.surrogate
    return state is not None and state.status in SETTLED and state.n_fitted == detail.n_points

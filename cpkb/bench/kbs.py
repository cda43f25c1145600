"""Scenario knowledge bases on a cpkb service, created and deleted through the typed client."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ServiceKbs:
    """A service at `url`; picklable, so each worker opens its own client."""

    url: str
    token: str | None = None

    def _client(self):  # the client is imported lazily: `cpkb --help` stays fast
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

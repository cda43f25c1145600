"""What the planner asks of a knowledge base: every call a knowledge session makes.

`client.CpkbClient` (HTTP) and `planner.knowledge.memory.InMemoryKnowledge` (this process, for
tests) both implement it; `tests/planner/knowledge/test_client_contract.py` runs one suite over
both, as Optuna's storage tests run over every storage.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Protocol

from contract.bindings import BindingIn, BindingOut, BindingsPage
from contract.models import (
    Graph,
    MatchResult,
    ModelsOut,
    PointIn,
    PointsSinceOut,
    SuggestIn,
    SuggestOut,
    TypeDetail,
)


class KnowledgeClient(Protocol):
    def post_points(self, kb: str, points: Sequence[PointIn]) -> Any:
        """Store points; each graph is hashed into its type (created if new)."""
        ...

    def match_types(self, kb: str, graphs: Sequence[Graph]) -> list[MatchResult]:
        """Each graph's type ID, whether it exists and its points; nothing is stored."""
        ...

    def suggest(self, kb: str, request: SuggestIn) -> SuggestOut:
        """The service's MPF suggestion."""
        ...

    def models(
        self, kb: str, type_ids: Sequence[str], known: dict[str, str] | None = None
    ) -> ModelsOut:
        """The types' current predictors, but those whose version is `known`."""
        ...

    def get_type(self, kb: str, type_id: str) -> TypeDetail:
        """A type with the state of its fit."""
        ...

    def points_since(
        self,
        kb: str,
        type_ids: Iterable[str],
        after_point_id: int | None = None,
        *,
        exclude_run: str | None = None,
    ) -> PointsSinceOut:
        """Points of these types stored after the cursor (None: the cursor alone), without
        those of run `exclude_run`."""
        ...

    def add_binding(self, kb: str, binding: BindingIn) -> BindingOut:
        """Store a binding list found for a task."""
        ...

    def bindings(
        self,
        kb: str,
        *,
        skeleton: str | None = None,
        task: str | None = None,
        after: int | None = None,
        exclude_run: str | None = None,
    ) -> BindingsPage:
        """Found bindings after the cursor `after`, oldest first."""
        ...

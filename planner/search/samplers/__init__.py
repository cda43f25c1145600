"""Node-expansion samplers behind one interface, found by method name.

`register(method, factory)` adds a sampler; `make(method, ...)` builds one. A factory takes
`seed`, `world` and `knowledge` (a `KnowledgeSession` for methods that use the knowledge base,
else None) as keywords and returns a `Sampler`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from planner.search.samplers.base import SampleContext, Sampler

SamplerFactory = Callable[..., Sampler]

_FACTORIES: dict[str, SamplerFactory] = {}
_USES_KNOWLEDGE: set[str] = set()


def register(method: str, factory: SamplerFactory, *, uses_knowledge: bool = False) -> None:
    _FACTORIES[method] = factory
    if uses_knowledge:
        _USES_KNOWLEDGE.add(method)


def _load_builtins() -> None:
    from planner.search.samplers import cp_bo, mcts_bo, quasi_random  # noqa: F401


def methods() -> list[str]:
    _load_builtins()
    return sorted(_FACTORIES)


def uses_knowledge(method: str) -> bool:
    _load_builtins()
    return method in _USES_KNOWLEDGE


def make(method: str, *, seed: int, world: Any, knowledge: Any = None) -> Sampler:
    _load_builtins()
    if method not in _FACTORIES:
        raise KeyError(f"unknown method {method!r}; known: {', '.join(sorted(_FACTORIES))}")
    return _FACTORIES[method](seed=seed, world=world, knowledge=knowledge)


__all__ = ["SampleContext", "Sampler", "make", "methods", "register", "uses_knowledge"]

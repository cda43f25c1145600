"""Node-expansion samplers behind one interface, found by method name.

`register(method, factory)` adds a sampler; `make(method, ...)` builds one. A factory takes
`seed`, `world`, `knowledge` (a `KnowledgeSession` for methods that use the knowledge base,
else None) and `config` (the run's `PlanConfig`) as keywords and returns a `Sampler`. A preset
method (`planner.config.PRESETS`) is its base method's sampler under the preset's configuration.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from planner.config import PRESETS, PlanConfig, base_method, method_config
from planner.search.samplers.base import SampleContext, Sampler

SamplerFactory = Callable[..., Sampler]

_FACTORIES: dict[str, SamplerFactory] = {}
_USES_KNOWLEDGE: set[str] = set()


def register(method: str, factory: SamplerFactory, *, uses_knowledge: bool = False) -> None:
    _FACTORIES[method] = factory
    if uses_knowledge:
        _USES_KNOWLEDGE.add(method)


@functools.cache
def _load_builtins() -> None:
    """The built-in samplers, registered here (not by their modules, which would import this
    package back)."""
    from planner.search.samplers import cp_bo, mcts_bo, optuna_tpe, quasi_random

    register("cp-bo", cp_bo.factory, uses_knowledge=True)
    register("mcts-bo", mcts_bo.factory)
    register("optuna-tpe", optuna_tpe.factory)
    register("quasi-random", quasi_random.factory)


def methods() -> list[str]:
    """Every method: the registered samplers and the presets of registered ones."""
    _load_builtins()
    return sorted({*_FACTORIES, *(m for m, p in PRESETS.items() if p.base in _FACTORIES)})


def uses_knowledge(method: str) -> bool:
    _load_builtins()
    return base_method(method) in _USES_KNOWLEDGE


def make(
    method: str,
    *,
    seed: int,
    world: Any,
    knowledge: Any = None,
    config: PlanConfig | None = None,
) -> Sampler:
    """The method's sampler under `config` (with a preset's switches applied)."""
    if method not in methods():
        raise KeyError(f"unknown method {method!r}; known: {', '.join(methods())}")
    factory = _FACTORIES[base_method(method)]
    return factory(
        seed=seed, world=world, knowledge=knowledge, config=method_config(method, config)
    )


__all__ = ["SampleContext", "Sampler", "make", "methods", "register", "uses_knowledge"]

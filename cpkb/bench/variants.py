"""Named variants of a method: a method under a fixed set of planner knobs, defined as data.

An ablation is a bench whose methods are variants (each extension of cp-bo off in turn), so
that every variant runs on the same seeds beside the same quasi-random baseline and lands in one
table. A variants file (YAML or JSON) maps each name to the method it runs and its overrides:

```yaml
variants:
  cp-bo-no-lookahead:
    method: cp-bo
    set: {cp_bo.lookahead: false, cp_bo.continuations: false}
```

A variant of a transfer method (`cp-bo-transfer`) runs its predecessors under the same knobs.
Each run's record keeps the variant's method (`base_method`) and overrides, besides the full
configuration the planner ran with.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.config import ConfigError, PlanConfig, read_data_file, typed_overrides


@dataclass(frozen=True)
class Variant:
    name: str
    method: str
    overrides: tuple[tuple[str, Any], ...]


def parse_variants(data: object, known_methods: set[str]) -> dict[str, Variant]:
    """Variants from a parsed file; a ConfigError names the first thing wrong."""
    if not isinstance(data, Mapping) or not isinstance(data.get("variants"), Mapping):
        raise ConfigError("a variants file holds a mapping `variants: {name: {method, set}}`")
    variants = {}
    for name, spec in data["variants"].items():
        if not isinstance(name, str) or not name or "," in name or name in known_methods:
            raise ConfigError(
                f"variant name {name!r} must be new, non-empty text without commas "
                "(not a method's name)"
            )
        if not isinstance(spec, Mapping) or set(spec) - {"method", "set"}:
            raise ConfigError(f"variant {name!r} takes `method` and `set` only")
        method = spec.get("method")
        if method not in known_methods:
            known = ", ".join(sorted(known_methods))
            raise ConfigError(f"variant {name!r}: unknown method {method!r} (known: {known})")
        overrides = spec.get("set") or {}
        if not isinstance(overrides, Mapping):
            raise ConfigError(f"variant {name!r}: `set` maps dotted keys to values")
        try:
            typed = typed_overrides(overrides)
            PlanConfig().with_overrides(typed)  # the values' ranges
        except ConfigError as exc:
            raise ConfigError(f"variant {name!r}: {exc}") from None
        variants[name] = Variant(name, method, tuple(sorted(typed.items())))
    return variants


def load_variants(path: str | Path, known_methods: set[str]) -> dict[str, Variant]:
    return parse_variants(read_data_file(path, "variants file"), known_methods)

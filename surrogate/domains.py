"""The decision domains the surrogate library works on, defined once.

These are plain frozen dataclasses, not the wire models: the service and the planner read a
request's or a snapshot's JSON form into them at their edges (`domain_from_json`), so the ML
library never depends on the HTTP schema. The JSON form is the wire contract's, so the wire
models' `model_dump()` converts directly. Bounds and choices are checked by the wire models;
here a malformed mapping is a `DomainError`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

Value = str | list[float]


class DomainError(ValueError):
    """A mapping that does not describe a domain."""


@dataclass(frozen=True)
class CategoricalDomain:
    """A finite set of named choices; `embedding` optionally maps each choice to a vector so
    that surrogates see geometry, not codes."""

    choices: tuple[str, ...]
    embedding: Mapping[str, tuple[float, ...]] | None = None
    kind: str = "categorical"


@dataclass(frozen=True)
class ContinuousDomain:
    """A box `low..high`; `frame` names the space the values are positions in, `heading` the
    index of a planar pose's heading dimension, `scale` the half extents in metres that the
    position dimensions span about the frame's centre, `relative_only` that the pose's own
    columns are left out where its relative pose to another of its frame is encoded, `periodic`
    that the heading is encoded on a circle (see `surrogate.encoding`)."""

    low: tuple[float, ...]
    high: tuple[float, ...]
    frame: str | None = None
    heading: int | None = None
    scale: tuple[float, float] | None = None
    relative_only: bool = False
    periodic: bool = False
    kind: str = "continuous"


Domain = CategoricalDomain | ContinuousDomain
Space = dict[str, Domain]


def categorical(
    choices: list[str] | tuple[str, ...], embedding: Mapping | None = None
) -> CategoricalDomain:
    """A categorical domain from lists (tests and callers that build spaces by hand)."""
    table = None if embedding is None else {k: tuple(map(float, v)) for k, v in embedding.items()}
    return CategoricalDomain(tuple(choices), table)


def continuous(
    low: list[float] | tuple[float, ...],
    high: list[float] | tuple[float, ...],
    frame: str | None = None,
    heading: int | None = None,
    scale: list[float] | tuple[float, ...] | None = None,
    relative_only: bool = False,
    periodic: bool = False,
) -> ContinuousDomain:
    """A continuous domain from lists."""
    if periodic and heading is None:
        raise ValueError("periodic needs a heading dimension")
    half = None if scale is None else (float(scale[0]), float(scale[1]))
    return ContinuousDomain(
        tuple(map(float, low)),
        tuple(map(float, high)),
        frame,
        heading,
        half,
        bool(relative_only),
        bool(periodic),
    )


def domain_from_json(obj: Mapping[str, Any]) -> Domain:
    """The domain of the wire contract's JSON form (`{"kind": "categorical", "choices": ...}`
    or `{"kind": "continuous", "low": ..., "high": ...}`)."""
    try:
        if obj["kind"] == "categorical":
            return categorical(obj["choices"], obj.get("embedding"))
        if obj["kind"] == "continuous":
            return continuous(
                obj["low"],
                obj["high"],
                obj.get("frame"),
                obj.get("heading"),
                obj.get("scale"),
                bool(obj.get("relative_only")),
                bool(obj.get("periodic")),
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise DomainError(f"not a domain: {exc}") from exc
    raise DomainError(f"unknown domain kind {obj.get('kind')!r}")


def domain_to_json(domain: Domain) -> dict[str, Any]:
    """The wire contract's JSON form of `domain` (None fields left out)."""
    if isinstance(domain, CategoricalDomain):
        out: dict[str, Any] = {"kind": domain.kind, "choices": list(domain.choices)}
        if domain.embedding is not None:
            out["embedding"] = {k: list(v) for k, v in domain.embedding.items()}
        return out
    out = {"kind": domain.kind, "low": list(domain.low), "high": list(domain.high)}
    if domain.frame is not None:
        out["frame"] = domain.frame
    if domain.heading is not None:
        out["heading"] = domain.heading
    if domain.scale is not None:
        out["scale"] = list(domain.scale)
    if domain.relative_only:
        out["relative_only"] = True
    if domain.periodic:
        out["periodic"] = True
    return out


def space_from_json(space: Mapping[str, Mapping[str, Any]]) -> Space:
    return {name: domain_from_json(obj) for name, obj in space.items()}


def space_to_json(space: Mapping[str, Domain]) -> dict[str, dict[str, Any]]:
    return {name: domain_to_json(domain) for name, domain in space.items()}

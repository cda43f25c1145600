"""One MPF suggestion: the core that the service's engine and the planner's snapshot cache both
call, so that both answer the same point for the same models, request and seed.

A `ModelSource` gives a type's decision space, current predictor and version; `suggest`
validates the request against those spaces, builds one MPF term per bound constraint, maximises
MPF away from the excluded points and from the suggestions still pending in a `PendingBook`
(a space-filling point when nothing constrains the request), and records what it served as
pending. Requests and answers are this library's own dataclasses; the service and the planner
read them from and write them to the wire contract's JSON form (`from_json` / `to_json`).
"""

from __future__ import annotations

import dataclasses
import secrets
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from surrogate.acquisition import MPF, ConstraintTerm, PendingPoints
from surrogate.config import OptimizerConfig
from surrogate.domains import Domain, Value, domain_to_json, space_from_json
from surrogate.encoding import EncodingError, encoder_for, same_domain, value_column
from surrogate.optimize import maximize_batch, space_filling
from surrogate.pending import Pending
from surrogate.predictors import FeasibilityPredictor


class InvalidRequest(ValueError):
    """A request that does not fit the types it binds; the message names the field."""


@dataclass(frozen=True)
class TypeModel:
    """What a suggestion needs of one type: its decision space and current predictor, and the
    version of the fit behind it (with how many points it was fitted on, and knows of)."""

    space: Mapping[str, Domain]
    predictor: FeasibilityPredictor
    version: str
    n_fitted: int
    n_points: int


class ModelSource(Protocol):
    """Where the models come from: the service's engine, the planner's snapshots, or memory
    (`surrogate.sources.InMemoryModels`). An unknown type raises the source's own error."""

    def model(self, type_id: str) -> TypeModel: ...


@dataclass(frozen=True)
class Constraint:
    type_id: str
    bind: Mapping[str, str]  # decision label of the type -> search variable


@dataclass(frozen=True)
class SuggestRequest:
    """As the wire contract's `SuggestIn`: `lookahead` variables are optimised jointly but only
    a hint in the answer, `n > 1` asks for a spread batch, no `seed` draws a fresh one."""

    space: Mapping[str, Domain]
    fixed: Mapping[str, Value] = field(default_factory=dict)
    constraints: Sequence[Constraint] = ()
    exclude: Sequence[Mapping[str, Value]] = ()
    lookahead: Sequence[str] = ()
    seed: int | None = None
    n: int = 1

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> SuggestRequest:
        """The request of the wire contract's JSON form (already validated by its schema)."""
        return cls(
            space=space_from_json(obj["space"]),
            fixed=dict(obj.get("fixed") or {}),
            constraints=tuple(
                Constraint(c["type_id"], dict(c["bind"])) for c in obj.get("constraints") or ()
            ),
            exclude=tuple(obj.get("exclude") or ()),
            lookahead=tuple(obj.get("lookahead") or ()),
            seed=obj.get("seed"),
            n=int(obj.get("n", 1)),
        )


@dataclass(frozen=True)
class SuggestedPoint:
    x: dict[str, Value]
    mpf: float
    p_feasible: dict[str, float]


@dataclass(frozen=True)
class SuggestAnswer:
    """The first point, the batch (for `n > 1`, the first among them), how it was found, the
    fit each type's model came from, and how many pending points it was kept away from."""

    x: dict[str, Value]
    mpf: float
    p_feasible: dict[str, float]
    batch: tuple[SuggestedPoint, ...]
    method: str
    n_fitted: dict[str, int]
    n_pending: int

    def to_json(self) -> dict[str, Any]:
        """The wire contract's JSON form (`SuggestOut`)."""
        return dataclasses.asdict(self)


def suggest(
    source: ModelSource,
    request: SuggestRequest,
    book: Pending,
    *,
    key: str,
    config: OptimizerConfig,
    hints: Sequence[Mapping[str, Value]] = (),
    preferred: int = 0,
    record: bool = True,
) -> SuggestAnswer:
    """The MPF maximiser over `request.space` for its constraints (a space-filling point when
    there are none), away from `exclude` and from the suggestions pending in `book` under `key`;
    the answer's points are recorded there as pending (unless `record` is false: a caller
    that may not write is answered without changing what others are told). `hints`: points in
    this request's variables that the maximiser scores besides its own candidates, the first
    `preferred` of them preferred (`surrogate.optimize.maximize_batch`). Raises InvalidRequest
    naming the field, SpaceExhausted when a finite space is wholly excluded, and whatever
    `source` raises for an unknown type."""
    _check_lookahead(request)
    models: dict[str, TypeModel] = {}
    terms: list[ConstraintTerm] = []
    for i, constraint in enumerate(request.constraints):
        if constraint.type_id not in models:
            models[constraint.type_id] = source.model(constraint.type_id)
        model = models[constraint.type_id]
        _check_binding(i, constraint, model, request)
        terms.append(
            ConstraintTerm.build(
                constraint.type_id, model.predictor, model.space, constraint.bind, request.fixed
            )
        )
    pending = book.for_request(key, frozenset(models))
    seed = request.seed if request.seed is not None else secrets.randbits(31)
    try:
        if terms:
            points = _mpf_points(
                terms, request, PendingPoints(tuple(pending)), seed, config, hints, preferred
            )
        else:
            x = space_filling(
                request.space,
                fixed=request.fixed,
                exclude=request.exclude,
                pending=pending,
                seed=seed,
            )
            points = [SuggestedPoint(x=x, mpf=0.5, p_feasible={})]
    except EncodingError as exc:
        raise InvalidRequest(str(exc)) from exc
    binds = [(c.type_id, c.bind) for c in request.constraints]
    for point in points if record else ():
        proposed = {v: value for v, value in point.x.items() if v not in request.lookahead}
        book.add(key, proposed, binds)
    first = points[0]
    return SuggestAnswer(
        x=first.x,
        mpf=first.mpf,
        p_feasible=first.p_feasible,
        batch=tuple(points) if request.n > 1 else (),
        method="mpf" if terms else "space-filling",
        n_fitted={type_id: model.n_fitted for type_id, model in models.items()},
        n_pending=len(pending),
    )


def _check_lookahead(request: SuggestRequest) -> None:
    for i, var in enumerate(request.lookahead):
        if var not in request.space:
            raise InvalidRequest(f"lookahead[{i}]: {var!r} is not a variable of space")
    if set(request.space) <= set(request.lookahead):
        raise InvalidRequest("lookahead: leaves no variable of space to suggest")


def _check_binding(
    i: int, constraint: Constraint, model: TypeModel, request: SuggestRequest
) -> None:
    """Every decision of the type bound, to a variable of the space (of the same domain) or to a
    valid fixed value; no label the type does not have."""
    bind, type_id = constraint.bind, constraint.type_id
    where = f"constraints[{i}].bind"
    for label in bind:
        if label not in model.space:
            known = sorted(model.space)
            raise InvalidRequest(f"{where}.{label}: not a decision of type {type_id} ({known})")
    for label, domain in model.space.items():
        if label not in bind:
            raise InvalidRequest(f"{where}: decision {label!r} of type {type_id} is not bound")
        var = bind[label]
        if var in request.space and not same_domain(domain, request.space[var]):
            shown = {k: v for k, v in domain_to_json(domain).items() if k != "embedding"}
            raise InvalidRequest(
                f"space.{var}: domain does not match decision {label!r} of type {type_id} ({shown})"
            )
        if var in request.fixed:
            try:
                value_column(f"fixed.{var}", domain, [request.fixed[var]])
            except EncodingError as exc:
                raise InvalidRequest(str(exc)) from exc
        elif var not in request.space:
            raise InvalidRequest(f"{where}.{label}: variable {var!r} is neither in space nor fixed")


def _mpf_points(
    terms: Sequence[ConstraintTerm],
    request: SuggestRequest,
    pending: PendingPoints,
    seed: int,
    config: OptimizerConfig,
    hints: Sequence[Mapping[str, Value]] = (),
    preferred: int = 0,
) -> list[SuggestedPoint]:
    """Up to `request.n` spread MPF maximisers (see `maximize_batch`), each with every type's
    P(feasible)."""
    mpf = MPF(list(terms), pending=pending)
    found = maximize_batch(
        mpf,
        request.space,
        fixed=request.fixed,
        exclude=request.exclude,
        seed=seed,
        config=config,
        n=request.n,
        distinct=[var for var in request.space if var not in request.lookahead],
        hints=hints,
        preferred=preferred,
    )
    xs = [s.x for s in found]
    per_term = mpf.per_term(encoder_for(request.space).columns(xs))
    return [_point(x, terms, per_term[:, i]) for i, x in enumerate(xs)]


def _point(x: dict, terms: Sequence[ConstraintTerm], per_term: np.ndarray) -> SuggestedPoint:
    """One answer point: each type's P(feasible) (a type bound twice: its lower one), and MPF."""
    p_feasible: dict[str, float] = {}
    for term, p in zip(terms, per_term, strict=True):
        p_feasible[term.name] = min(float(p), p_feasible.get(term.name, 1.0))
    mpf = min(p_feasible.values()) if p_feasible else 0.5
    return SuggestedPoint(x=x, mpf=mpf, p_feasible=p_feasible)

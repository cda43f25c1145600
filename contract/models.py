"""Wire contract v1: the pydantic models shared by the client and the server.

Defined once here; `server/` imports them, so the two sides cannot drift.
A decision value is a choice name (categorical) or a list of floats (continuous).
"""

from __future__ import annotations

import math
from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)
from pydantic.config import JsonDict

MAX_LABEL = 128
MAX_CHOICES = 64
MAX_DIM = 32
MAX_BATCH = 32  # points in one suggest answer
MAX_NODES = 64
MAX_EDGES = 256
MAX_POINTS_PER_POST = 1000
MAX_SOURCE_DEPTH = 32  # nesting of lists and objects in a point's `source`
MAX_SEED = 2**63 - 1


def _storable(text: str) -> str:
    """Text both backends store alike: PostgreSQL refuses NUL in text columns where SQLite keeps
    it, and a lone surrogate (JSON's "\\ud800") is not UTF-8, so no database can store it."""
    if "\x00" in text:
        raise ValueError("must not contain NUL (\\u0000) characters")
    if not text.isascii():
        try:
            text.encode("utf-8")
        except UnicodeEncodeError:
            raise ValueError("must not contain lone surrogates (\\ud800-\\udfff)") from None
    return text


def _not_boolean(value: Any) -> Any:
    """JSON `true` is not the number 1: a flag sent as a coordinate is a mistake."""
    if isinstance(value, bool):
        raise ValueError("a boolean is not a number")
    return value


Text = Annotated[str, AfterValidator(_storable)]
# JSON as Python reads it allows NaN and Infinity; no route may take one in (SQLite would store
# it, and every later reader of that row would fail on it).
Number = Annotated[float, BeforeValidator(_not_boolean), Field(allow_inf_nan=False)]
Label = Annotated[Text, Field(min_length=1, max_length=MAX_LABEL)]
Value = Text | list[Number]


class _Strict(BaseModel):
    """A request model: unknown fields and non-finite numbers are refused (422)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


# Examples for the OpenAPI schema (/docs): an inverse-kinematics failure of one grasp and pose.
_DIR: JsonDict = {"kind": "categorical", "choices": ["front", "right", "top", "back", "left"]}
_POSE: JsonDict = {"kind": "continuous", "low": [0.0, 0.0, -3.14], "high": [1.0, 1.0, 3.14]}
_GRAPH_EXAMPLE: JsonDict = {
    "nodes": [
        {"id": "f", "role": "failure", "label": "Inv-kin"},
        {"id": "d", "role": "decision", "label": "#dir", "domain": _DIR},
        {"id": "p", "role": "decision", "label": "#pose", "domain": _POSE},
        {"id": "c0", "role": "context", "label": "shelf"},
    ],
    "edges": [
        {"source": "d", "target": "f", "label": "grasp"},
        {"source": "p", "target": "f", "label": "pose"},
        {"source": "c0", "target": "f", "label": "collides"},
    ],
}
_POINT_EXAMPLE: JsonDict = {
    "graph": _GRAPH_EXAMPLE,
    "x": {"#dir": "top", "#pose": [0.42, 0.7, 1.57]},
    "feasible": False,
    "source": {"task": "desk", "run": "desk-cp-bo-7", "rollout": 12, "worker": "host:4242"},
    "key": "desk-cp-bo-7/12/0",
}
_TYPE_ID_EXAMPLE = "3f9a0c1d2b4e5f60"


class CategoricalDomain(_Strict):
    """A finite set of named choices; `embedding` optionally maps each choice to a vector
    (a grasp direction to its unit approach vector) so that surrogates see geometry, not codes."""

    kind: Literal["categorical"] = "categorical"
    choices: list[Label] = Field(min_length=1, max_length=MAX_CHOICES)
    embedding: dict[Label, list[Number]] | None = None

    @model_validator(mode="after")
    def _check(self) -> CategoricalDomain:
        if len(set(self.choices)) != len(self.choices):
            raise ValueError("choices must be unique")
        if self.embedding is not None:
            if set(self.embedding) != set(self.choices):
                raise ValueError("embedding must have exactly one vector per choice")
            dims = {len(v) for v in self.embedding.values()}
            if len(dims) != 1 or 0 in dims:
                raise ValueError("embedding vectors must share one non-zero dimension")
            if not all(math.isfinite(f) for v in self.embedding.values() for f in v):
                raise ValueError("embedding values must be finite")
        return self


class ContinuousDomain(_Strict):
    """A box: `low[i] < high[i]`, finite, 1 to MAX_DIM dimensions.

    `frame` optionally names the space the values are positions in (a placement's region):
    where a type has two decisions in one frame, its surrogate also sees how far apart they are,
    so that "box 3 collides with box 1" is learned once, not anew for each place of box 1.

    `heading` optionally marks a framed planar pose `(x, y, heading)`: the index of the heading
    dimension, whose `[low, high]` spans one turn `[-pi, pi)` in the frame's axes; the other two
    are the position, taken as equally scaled (a square frame) unless `scale` is given. Two
    such poses in one frame are then also seen in each other's heading frame: where one lies
    across or along the hand that places the other (see `surrogate.encoding`).

    `scale` optionally gives, for such a pose, the half extents in metres `[half_x, half_y]`
    that the position dimensions span about the frame's centre: the relative pose is then
    measured in metres, right for rectangular frames and for poses scaled unlike each other.

    `relative_only` marks such a pose whose own columns (where it lies in the frame, its heading
    there) are not model inputs in a type that also holds another pose of its frame: the type
    sees only their relative pose, as a collision between two placed bodies depends on it.

    `periodic` marks such a pose's heading as the angle it is: `low` and `high` are one heading,
    and the surrogate sees the heading on a circle, so that two headings a few degrees either
    side of the seam are near, not a whole range apart."""

    kind: Literal["continuous"] = "continuous"
    low: list[Number] = Field(min_length=1, max_length=MAX_DIM)
    high: list[Number] = Field(min_length=1, max_length=MAX_DIM)
    frame: Label | None = None
    heading: int | None = Field(default=None, ge=0, le=2)
    scale: list[Number] | None = Field(default=None, min_length=2, max_length=2)
    relative_only: bool | None = None  # None (off) stays out of the type's canonical form
    periodic: bool | None = None  # as relative_only

    @field_validator("relative_only", "periodic")
    @classmethod
    def _off_is_none(cls, value: bool | None) -> bool | None:
        return True if value else None

    @model_validator(mode="after")
    def _check(self) -> ContinuousDomain:
        if len(self.low) != len(self.high):
            raise ValueError("low and high must have the same length")
        if not all(math.isfinite(v) for v in [*self.low, *self.high]):
            raise ValueError("bounds must be finite numbers")
        if any(lo >= hi for lo, hi in zip(self.low, self.high, strict=True)):
            raise ValueError("every low must be below its high")
        if self.heading is not None and (self.frame is None or len(self.low) != 3):
            raise ValueError("heading needs a frame and three dimensions (x, y, heading)")
        if self.scale is not None:
            if self.heading is None:
                raise ValueError("scale needs a heading (a framed planar pose)")
            if not all(math.isfinite(v) and v >= 0 for v in self.scale):
                raise ValueError("scale must be two finite half extents >= 0 (metres)")
        if self.relative_only and self.heading is None:
            raise ValueError("relative_only needs a heading (a framed planar pose)")
        if self.periodic and self.heading is None:
            raise ValueError("periodic needs a heading (a framed planar pose)")
        return self


Domain = Annotated[CategoricalDomain | ContinuousDomain, Field(discriminator="kind")]
Role = Literal["failure", "decision", "context", "connection"]


class Node(_Strict):
    id: Label = Field(description="Unique within the graph; any name (it is not hashed).")
    role: Role = Field(description="failure (one per graph), decision, context or connection.")
    label: Label = Field(
        description="What the vertex is in the workspace: a failure kind (`Inv-kin`), a "
        "decision variable (`#pose`, unique among decisions) or a body (`shelf`)."
    )
    domain: Domain | None = Field(
        default=None, description="A decision's domain (required for decisions, else none)."
    )


class Edge(_Strict):
    source: Label = Field(description="The `id` of the vertex the edge leaves.")
    target: Label = Field(description="The `id` of the vertex the edge enters.")
    label: Annotated[Text, Field(max_length=MAX_LABEL)] = Field(
        default="", description="What the edge means (`grasp`, `collides`); hashed."
    )


class Graph(_Strict):
    """A causal graph of one failure: failure, decision, context and connection vertexes."""

    model_config = ConfigDict(json_schema_extra={"examples": [_GRAPH_EXAMPLE]})

    nodes: list[Node] = Field(min_length=1, max_length=MAX_NODES, description="The vertexes.")
    edges: list[Edge] = Field(
        default_factory=list, max_length=MAX_EDGES, description="Directed, labelled edges."
    )


class Source(BaseModel):
    """Provenance of a point; extra keys are kept: any JSON nested at most MAX_SOURCE_DEPTH
    deep (every reader of the point must be able to serialise it back), text storable as in
    the rest of the contract."""

    model_config = ConfigDict(
        extra="allow",
        json_schema_extra={"x-max-depth": MAX_SOURCE_DEPTH},
    )

    task: Text | None = Field(default=None, max_length=MAX_LABEL, description="The task run.")
    run: Text | None = Field(
        default=None,
        max_length=MAX_LABEL,
        description="The run the point came from (`exclude_run` of points/since matches it).",
    )
    rollout: int | None = Field(default=None, description="The rollout within the run.")
    worker: Text | None = Field(
        default=None, max_length=MAX_LABEL, description="Who posted it (host:pid)."
    )
    time: datetime | None = Field(default=None, description="When the point was observed.")

    @model_validator(mode="after")
    def _check_extra(self) -> Source:
        for key, value in (self.model_extra or {}).items():
            _storable_at(key, "a key of source")
            _check_json(value, key, 1)
        return self


def _check_json(value: Any, where: str, depth: int) -> None:
    """Every key and string of `value` storable; lists and objects at most MAX_SOURCE_DEPTH
    deep, counting the `source` object itself as the first level (`depth`: its container's)."""
    if isinstance(value, str):
        _storable_at(value, where)
        return
    if not isinstance(value, dict | list):
        return
    if depth >= MAX_SOURCE_DEPTH:
        raise ValueError(f"{where!a}: nested deeper than {MAX_SOURCE_DEPTH} levels")
    items = value.items() if isinstance(value, dict) else enumerate(value)
    for key, item in items:
        if isinstance(key, str):
            _storable_at(key, f"a key in {where}")
        inner = f"{where}.{key}" if isinstance(key, str) else f"{where}[{key}]"
        _check_json(item, inner, depth + 1)


def _storable_at(text: str, where: str) -> None:
    try:
        _storable(text)
    except ValueError as exc:
        raise ValueError(f"{where!a}: {exc}") from None


class PointIn(_Strict):
    """One observation of a constraint: the failure's causal graph (its type) and the decision
    values tried, feasible or not."""

    model_config = ConfigDict(json_schema_extra={"examples": [_POINT_EXAMPLE]})

    graph: Graph = Field(description="The causal graph; its hash is the point's CP type.")
    x: dict[Label, Value] = Field(
        description="A value for every decision label of the graph: a choice name "
        "(categorical) or a list of floats within the domain's box (continuous)."
    )
    feasible: bool = Field(description="Whether the constraint held at `x`.")
    source: Source | None = Field(default=None, description="Provenance, stored with the point.")
    key: Annotated[Text, Field(min_length=1, max_length=200)] | None = Field(
        default=None,
        description="Idempotency key: the same key and point again stores nothing (a replay); "
        "the same key with another point is a 409.",
    )


class PointsIn(_Strict):
    model_config = ConfigDict(json_schema_extra={"examples": [{"points": [_POINT_EXAMPLE]}]})

    points: list[PointIn] = Field(
        min_length=1,
        max_length=MAX_POINTS_PER_POST,
        description=f"1 to {MAX_POINTS_PER_POST} points, stored in one transaction.",
    )


class PointResult(BaseModel):
    type_id: str
    point_id: int
    new_type: bool


class PointsOut(BaseModel):
    results: list[PointResult]


class MatchIn(_Strict):
    model_config = ConfigDict(json_schema_extra={"examples": [{"graphs": [_GRAPH_EXAMPLE]}]})

    graphs: list[Graph] = Field(
        min_length=1,
        max_length=MAX_POINTS_PER_POST,
        description="Graphs to hash into type IDs; nothing is stored.",
    )


class MatchResult(BaseModel):
    type_id: str
    exists: bool
    n_points: int


class KnowledgeBaseIn(_Strict):
    """A name that is one path segment of the API's URLs: `.` and `..` are not (clients and
    proxies resolve them away)."""

    model_config = ConfigDict(json_schema_extra={"examples": [{"name": "lab"}]})

    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")] = Field(
        description="Letters, digits, `_`, `.` and `-`; not `.` or `..`."
    )

    @model_validator(mode="after")
    def _check_name(self) -> KnowledgeBaseIn:
        if self.name in (".", ".."):
            raise ValueError(f"{self.name!r} is a path step, not a knowledge-base name")
        return self


class KnowledgeBase(BaseModel):
    name: str
    n_types: int = 0
    n_points: int = 0
    created_at: datetime | None = None


class TypeSummary(BaseModel):
    type_id: str
    failure: str
    decisions: list[str]
    context: list[str]
    n_points: int
    n_infeasible: int
    created_at: datetime | None = None
    updated_at: datetime | None = None


class SurrogateState(BaseModel):
    """What the per-type surrogate knows right now; `None` fields until a first fit."""

    model_config = ConfigDict(extra="allow")

    status: str
    version: int | None = None
    n_fitted: int = 0
    lengthscales: list[float] | None = None
    fit_seconds: float | None = None
    train_accuracy: float | None = None


class TypeDetail(TypeSummary):
    graph: Graph
    space: dict[str, Domain]
    surrogate: SurrogateState | None = None


class PointOut(BaseModel):
    point_id: int
    type_id: str
    x: dict[str, Value]
    feasible: bool
    source: dict[str, Any] | None = None
    key: str | None = None
    created_at: datetime | None = None


class PointsPage(BaseModel):
    points: list[PointOut]
    next_cursor: str | None = None


MAX_WATCHED_TYPES = 512  # types in one `points/since` request


class PointsSinceIn(_Strict):
    """Other writers' points of these types stored after point `after_point_id` (a cursor
    this service gave out): what a running planner folds into its models between fits.
    Without `after_point_id` the answer has no points, only the cursor to start from. A type
    ID the knowledge base does not hold is watched, not refused: its points come once another
    writer creates it. `exclude_run` leaves out the caller's own points (`source.run`)."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "type_ids": [_TYPE_ID_EXAMPLE],
                    "after_point_id": 1200,
                    "exclude_run": "desk-cp-bo-7",
                }
            ]
        }
    )

    type_ids: list[Label] = Field(
        max_length=MAX_WATCHED_TYPES, description="The watched types (stored or not yet)."
    )
    after_point_id: int | None = Field(
        default=None, ge=0, le=MAX_SEED, description="The cursor of the previous answer."
    )
    exclude_run: Text | None = Field(
        default=None, max_length=MAX_LABEL, description="Leave out points of this `source.run`."
    )
    limit: int = Field(
        default=MAX_POINTS_PER_POST,
        ge=1,
        le=MAX_POINTS_PER_POST,
        description="At most this many points in the answer.",
    )


class LivePoint(BaseModel):
    point_id: int
    type_id: str
    x: dict[str, Value]
    feasible: bool
    run: str | None = None
    rollout: int | None = None


class PointsSinceOut(BaseModel):
    """`cursor`: the `after_point_id` of the next request; `more`: the limit cut this answer
    short (ask again at once)."""

    points: list[LivePoint]
    cursor: int
    more: bool = False


class PredictIn(_Strict):
    model_config = ConfigDict(
        json_schema_extra={"examples": [{"x": [{"#dir": "top", "#pose": [0.42, 0.7, 1.57]}]}]}
    )

    x: list[dict[Label, Value]] = Field(
        min_length=1,
        max_length=MAX_POINTS_PER_POST,
        description="Points, each a value for every decision label of the type.",
    )


class PredictOut(BaseModel):
    p_feasible: list[float]


class Constraint(_Strict):
    type_id: Label = Field(description="A CP type of the knowledge base.")
    bind: dict[Label, Label] = Field(
        min_length=1,
        description="The type's decision labels mapped onto this request's variables (names "
        "in `space` or `fixed`): a type's `#dir` is `#dir2` at a task's second grasp.",
    )


class SuggestIn(_Strict):
    """`lookahead` names space variables that are later decisions: MPF is maximised jointly over
    them (the answer for the other variables must leave a feasible continuation), their values
    in `x` are only a hint, and they are not recorded as pending. An `exclude` point may give
    only some variables: it excludes every point that agrees with it on those. With `n > 1` the
    answer's `batch` holds up to `n` points (the first is `x`), each the best away from those
    before it on the non-lookahead variables: what `n` successive suggestions at one node would
    be if the model did not change in between, for the price of one."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "space": {"g": _DIR, "p": _POSE},
                    "constraints": [
                        {"type_id": _TYPE_ID_EXAMPLE, "bind": {"#dir": "g", "#pose": "p"}}
                    ],
                    "exclude": [{"g": "front"}],
                    "seed": 0,
                }
            ]
        }
    )

    space: dict[Label, Domain] = Field(
        min_length=1, max_length=MAX_DIM, description="The variables to choose, by name."
    )
    fixed: dict[Label, Value] = Field(
        default_factory=dict, description="Variables already decided, by name."
    )
    constraints: list[Constraint] = Field(
        default_factory=list,
        max_length=64,
        description="The CP types whose feasibility the answer maximises (the minimum of them).",
    )
    exclude: list[dict[Label, Value]] = Field(
        default_factory=list,
        max_length=10_000,
        description="Points not to answer (a node's siblings); a partial one excludes all that "
        "agree with it.",
    )
    lookahead: list[Label] = Field(
        default_factory=list,
        max_length=MAX_DIM,
        description="Variables of `space` that are later decisions, maximised jointly.",
    )
    seed: int | None = Field(
        default=None, ge=0, le=MAX_SEED, description="Makes the answer repeatable."
    )
    n: int = Field(1, ge=1, le=MAX_BATCH, description="Points in the answer's `batch`.")


class SuggestedPoint(BaseModel):
    x: dict[str, Value]
    mpf: float
    p_feasible: dict[str, float]


class SuggestOut(BaseModel):
    """`method`: how the point was found (mpf, space-filling; `-local` in a planner's own
    process); `n_fitted`: the fit each type's model came from; `n_pending`: the pending
    suggestions it was kept away from."""

    x: dict[str, Value]
    mpf: float
    p_feasible: dict[str, float]
    batch: list[SuggestedPoint] = Field(default_factory=list)
    method: str = "mpf"
    n_fitted: dict[str, int] = Field(default_factory=dict)
    n_pending: int = 0


class ModelsIn(_Strict):
    """`known` maps a type to the version of its model the caller holds: the answer leaves
    those types out unless their model has changed since."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [{"type_ids": [_TYPE_ID_EXAMPLE], "known": {_TYPE_ID_EXAMPLE: "40"}}]
        }
    )

    type_ids: list[Label] = Field(
        min_length=1, max_length=64, description="The types whose models to send."
    )
    known: dict[Label, Text] = Field(
        default_factory=dict, description="Type ID to the model version the caller holds."
    )


class ModelSnapshot(BaseModel):
    """A type's current predictor (`surrogate.snapshot` JSON), with what it was fitted on: a
    planner evaluates MPF with it in its own process, as `suggest` would with no point pending.
    `version` names the fit (it changes when a fit lands, not when points arrive: the points
    stored since the fit are in `predictor`, and a planner adds its own newer ones itself)."""

    type_id: str
    version: str
    space: dict[str, Domain]
    n_points: int
    n_fitted: int
    predictor: dict[str, Any]


class ModelsOut(BaseModel):
    """The changed models, and the settings the service's own `suggest` uses: the optimiser's,
    and how long a served suggestion stays pending."""

    models: list[ModelSnapshot]
    optimizer: dict[str, float | int | bool]
    pending_ttl_s: float


class Health(BaseModel):
    model_config = ConfigDict(extra="allow")

    status: Literal["ok"]
    version: str
    database: str

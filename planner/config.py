"""Every tuning knob of a planner run, as data: one frozen dataclass per part, one default each.

A variant of the planner is a configuration, not a commit: `PlanConfig` groups the parts, the CLI
changes any knob by its dotted name (`--set cp_bo.lookahead=false`, `--set search.pw_k=10`) or
from a YAML/JSON file, and each run records the whole configuration (`PlanConfig.to_dict`).

The switches of the outlook- and hopeless-driven tree behaviour live in `SearchConfig`, since the
tree applies them; only samplers that rate their proposals (cp-bo) ever trigger them. A method
may be a named preset of another (`PRESETS`): `cp-bo-paper` is cp-bo with every extension beyond
the paper's CP-BO switched off, so that only the choice of a new child differs from quasi-random.
"""

from __future__ import annotations

import dataclasses
import json
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from surrogate.config import OptimizerConfig


class ConfigError(ValueError):
    """An unknown key, a value of the wrong type or range, or an unreadable configuration file."""


def _at_least(config: object, **bounds: float) -> None:
    """Refuse a knob below its bound (a batch of 0 points, a negative exploration weight)."""
    for name, bound in bounds.items():
        value = getattr(config, name)
        if value < bound:
            sections = {kind: section for section, kind in _section_types().items()}
            key = f"{sections.get(type(config), type(config).__name__)}.{name}"
            raise ConfigError(f"{key} must be at least {bound}, not {value}")


RESTART_SCHEDULES = ("luby", "geometric")


@dataclass(frozen=True)
class SearchConfig:
    """PW-UCT's knobs (`planner.search.tree`)."""

    pw_k: float = 13.5
    """The progressive-widening law: a node widens when N > k |C|^2."""
    ucb_c: float = 0.1
    """UCB's exploration weight."""
    hopeless_widening: bool = True
    """A node whose proposals the knowledge base has given up on lets its parent widen."""
    hopeless_ratio: float = 0.6
    """A node is hopeless while its best proposal is less likely to be feasible than this
    fraction of its first one. Relative, because a type's base rate sets the scale (a
    well-fitted type with few feasible points never predicts much above its base rate)."""
    hopeless_min_children: int = 8
    """Only a node with this many children can be hopeless: a refit that lowers every
    prediction at once must not let every parent widen at every visit."""
    outlook_widening: bool = True
    """An untried value rated `outlook_ratio` times above the best open child's outlook opens
    at once instead of waiting for the PW law."""
    outlook_selection: bool = True
    """UCB selects only among the children within `outlook_ratio` of the best outlook."""
    outlook_ratio: float = 1.25
    """The factor of both outlook rules: a grasp that no placement can follow, or a box placed
    where the next has no room, loses the search to a value the knowledge base expects to work."""
    outlook_free_every: int = 4
    """Every this many visits a node selects by plain UCB, whatever the outlooks: completeness."""
    outlook_prior_weight: float = 4.0
    """A categorical child's outlook is the knowledge base's P(feasible) below it as a Beta
    prior worth this many rollouts, updated by the failed rollouts through it:
    `w p / (w + failures)`. The knowledge base learns a failure only where it happened (until a
    refit spreads it), so counted failures make the search leave a child once another child's
    evidence is better. A continuous child's outlook is the model's view below it."""

    restart_unit: int = 64
    """Rollouts in one unit of Luby's restart schedule (runs of 1, 1, 2, 1, 1, 2, 4, ... units):
    at the end of each run the tree starts afresh and the knowledge base is kept. Rewards back
    up by max, so UCB keeps to a child whose rollouts once failed deepest (a grasp that lifts
    the body but can never place it); a fresh tree opens its first children with every failure
    learned so far. Luby's schedule is within a log factor of the best fixed schedule whatever
    the distribution of run lengths. Only a sampler whose knowledge outlives the tree restarts
    (cp-bo; `Sampler.keeps_knowledge`), unless `restart_without_knowledge`. 0: one tree for
    the whole run (the paper, and `cp-bo-paper`)."""
    restart_without_knowledge: bool = False
    """Restart (and redraw, with `restart_redraws`) a sampler that keeps nothing beyond the
    tree too, such as quasi-random: the strongest search without learning, the baseline every
    claim is made against (`quasi-random-restarts`). Off: only a sampler that keeps knowledge
    restarts, and quasi-random is the paper's one tree."""
    restart_schedule: str = "luby"
    """`luby`, or `geometric`: each tree gets twice the rollouts of the one before (1, 2, 4, ...
    units), so a task that needs one long tree loses at most the rollouts spent before it, at
    the cost of cutting a stuck tree later."""
    restart_redraws: bool = True
    """A restarted tree draws the randomised checks afresh (IK restarts, the motion planner's
    seed), as a further attempt does: a pick that passed in an arm configuration from which no
    placement's motion succeeds is drawn again by the next tree, where one tree keeps it for
    ever (a passed choice is never retried). And a tree that closes on failures no draw proved
    (every grasp's IK found nothing) restarts instead of ending the search. Off: every tree
    draws as the first did."""

    inconclusive_retries: int = 3
    """Further attempts a categorical choice gets after failing inconclusively (IK restarts or
    the motion planner found nothing; not a proof of infeasibility), where no continuous decision
    lies above it: with one attempt, a seed whose first IK of the only grasp that can pick out
    of clutter is unlucky never solves its task. 0: a failed choice is closed for good."""

    def __post_init__(self) -> None:
        if self.restart_schedule not in RESTART_SCHEDULES:
            raise ConfigError(
                f"search.restart_schedule is one of {', '.join(RESTART_SCHEDULES)},"
                f" not {self.restart_schedule!r}"
            )
        _at_least(
            self,
            inconclusive_retries=0,
            restart_unit=0,
            pw_k=0.0,
            ucb_c=0.0,
            hopeless_ratio=0.0,
            hopeless_min_children=0,
            outlook_ratio=1.0,
            outlook_free_every=1,
            outlook_prior_weight=1e-9,
        )


@dataclass(frozen=True)
class CpBoConfig:
    """CP-BO's sampler (`planner.search.samplers.cp_bo`) and its use of the knowledge base."""

    batch: int = 4
    """Points per suggestion request: a fit takes longer than a few rollouts, so successive
    requests would mostly see one model; a spread batch costs one request instead of `batch`."""
    batch_max_age: int = 8
    """Rollouts after which a node's batch (or a continuation) is asked for anew, to follow
    the refits."""
    outlook_max_age: int = 32
    """Rollouts after which reading a node's outlook (the tree's look at its best untried value,
    `SearchConfig.outlook_widening`) asks for its batch anew; younger, the batch's best is read
    as it stands. A read is asked far more often than a value is taken, and a request is a
    guided rollout's largest cost after the simulation."""
    lookahead: bool = True
    """A decision's suggestion also weighs the types on later decisions (optimised jointly);
    the paper's rule constrains a decision only by types on it and earlier ones."""
    continuations: bool = True
    """A looked-ahead answer's later values seed the nodes it leads to (one suggestion per
    fresh descent, not one per decision)."""
    prematch: bool = True
    """Before the search, activate the known types of every graph the task could produce; the
    paper activates a type when its failure is met."""

    def __post_init__(self) -> None:
        _at_least(self, batch=1, batch_max_age=0, outlook_max_age=0)


@dataclass(frozen=True)
class MctsBoConfig:
    """MCTS-BO's GP-UCB sampler (`planner.search.samplers.mcts_bo`)."""

    beta: float = 8.0
    """UCB's exploration weight, in the fit's standardised units."""
    min_children: int = 2
    """Children a node needs (with differing targets) before the GP guides it."""
    graded: bool = True
    """Regress on the reward graded within the failed check; false: the tree's plain reward."""
    max_children_fitted: int = 150
    """Exact GP is O(n^3); the most recent children carry the signal."""
    fit_iterations: int = 60
    """Adam steps per fit (warm starts need a third of this)."""

    def __post_init__(self) -> None:
        _at_least(self, beta=0.0, min_children=2, max_children_fitted=2, fit_iterations=1)


@dataclass(frozen=True)
class QuasiRandomConfig:
    """The Voronoi sampler (`planner.search.samplers.quasi_random`), also every guided sampler's
    fallback where it has no guidance."""

    candidates_per_dim: int = 10
    """Uniform candidates per dimension; the farthest from the siblings is proposed."""

    def __post_init__(self) -> None:
        _at_least(self, candidates_per_dim=1)


@dataclass(frozen=True)
class OptunaTpeConfig:
    """Optuna's TPE as a peer sampler (`planner.search.samplers.optuna_tpe`)."""

    n_startup_trials: int = 10
    """Random trials before TPE models a variable (Optuna's default)."""
    max_categorical_asks: int = 8
    """Asks for an untried choice before falling back to a uniform untried one."""

    def __post_init__(self) -> None:
        _at_least(self, n_startup_trials=0, max_categorical_asks=1)


@dataclass(frozen=True)
class KnowledgeConfig:
    """The planner's side of the knowledge base (`planner.knowledge`)."""

    refresh_rollouts: int = 3
    """Rollouts between two fetches of one type's model (a fit takes longer than a few)."""
    match_chunk: int = 500
    """Graphs per types/match request (the contract allows up to 1000)."""
    post_linger_ms: float = 100.0
    """The background poster waits this long after a rollout's points for later ones to join
    them in one request (`planner.knowledge.poster`); a wait for a batch to be stored cuts it
    short. Each request costs the planner's process CPU time while its thread holds the GIL.
    0: each batch goes as soon as the poster is free."""
    deterministic: bool = False
    """Wait for each refit this planner's points ask for, and post and fetch in the foreground:
    the same seed on a fresh knowledge base gives the same run, at the cost of the waits."""
    fit_wait_s: float = 120.0
    """The longest wait for one refit in deterministic mode (then the run goes on, noted)."""
    square_grasps: bool = True
    """A grasp holding a body with a square footprint being placed is encoded with all its side
    grasps as one (`planner.failures.graphs`); the paper encodes the grasp as declared."""
    grasp_symmetry: bool = True
    """A grasp holding any box being placed is encoded with opposite faces alike (front and
    back, right and left): the placing hand's pose is the same and the box, turned half a turn,
    occupies the same footprint, so what one face taught about a region holds for the other
    (`planner.failures.graphs`); the paper encodes the grasp as declared."""
    periodic_headings: bool = True
    """A placement's heading is encoded on a circle (`surrogate.encoding`): the two ends of its
    seed's range are one heading, which the paper's encoding, a plain column, puts furthest
    apart."""
    relative_pairs: bool = True
    """In a type holding two placements of one region (a box placed beside another), the
    model's inputs are their relative pose alone, not where each lies in the region as well
    (`surrogate.encoding`): what one pair of boxes taught (in a predecessor, or earlier in the
    run) then holds wherever the next pair stands. The paper's inputs are the decisions'
    values."""
    movable_names: bool = False
    """A movable body's vertex in a failure graph is labelled with its name, as the paper's are;
    off: `movable`, so that the failures of one box placed beside another are one type whichever
    boxes they are (pack's second box beside its first, its third beside its second, and a
    predecessor's boxes of other names), and what one pair taught, the others use
    (`planner.failures.graphs`); a task with one movable body gets the same types either way."""
    prior_counts: float = 2.0
    """With s > 0, the stated prior of a type without a fit counts its points, a Beta prior of
    s pseudo-points updated by kernel-weighted counts (`surrogate.predictors.PriorPredictor`),
    instead of rating each place by its nearest point alone: a choice that failed once is rated
    1/3 (s = 2) rather than 0.05, one that failed twenty times 1/21, where the nearest-point
    form rates both alike and prefers the choice that failed most, as long as it failed at
    other placements. Applies where the planner maximises MPF itself; 0: the nearest-point
    form (`cp-bo-paper` pins it)."""
    spread_walls: bool = OptimizerConfig().spread_walls
    """Where this planner maximises MPF, the margin rule's spread keeps a node's children off
    the faces of its box (`surrogate.avoid.AvoidSet.spread`); off, its most spread point may
    lie on a face or in a corner, as the quasi-random baseline's does. The service's own
    suggestions (`--suggest-in service`) follow the service's setting."""
    live_points: bool = True
    """Take in other planners' new points of the active types while running, and activate at
    once the types they create (`planner.knowledge.live`); not in deterministic mode, whose
    runs must not depend on what others post meanwhile."""
    live_every_rollouts: int = 1
    """Rollouts between two polls for other planners' points (with `live_points`)."""
    live_idle_max: int = 8
    """With `live_points` or `follow_found`, a poll that brought nothing spaces the next one
    out, doubling the rollouts between them up to this many; one that brings something goes
    back to `live_every_rollouts` (`planner.knowledge.polls`). 1: every `live_every_rollouts`
    rollouts. Each poll is a request read in a thread of the planner's process, which holds the
    GIL meanwhile, and a planner alone polls for nothing."""
    live_hints: int = 8
    """With `live_points`, the newest other planners' feasible points kept per type, scored as
    candidates by this planner's MPF maximisation (each run's also merged into one, its latest
    chain of passed decisions) and preferred among the near-best ones, so that a binding another
    planner found is tried here before a fit has taken it in
    (`planner.knowledge.live.PeerHints`; where the planner maximises MPF itself, the
    default `--suggest-in planner`); 0: none."""
    live_hints_limit: int = 32
    """The most such candidates one suggestion scores (the newest first)."""
    follow_found: bool = True
    """Follow, as the next rollout, each binding list another run of this task found and
    stored in the knowledge base (`planner.knowledge.found.FoundBindings`): those found before
    this run, read when it starts, and with `live_points` (not in deterministic mode) those
    found while it runs; this run stores its own. A task is known by its name and plan
    skeleton (a predecessor's bindings are not followed)."""

    def __post_init__(self) -> None:
        _at_least(
            self,
            refresh_rollouts=0,
            match_chunk=1,
            post_linger_ms=0.0,
            fit_wait_s=0.0,
            live_every_rollouts=1,
            live_idle_max=1,
            live_hints=0,
            live_hints_limit=1,
            prior_counts=0.0,
        )
        if self.match_chunk > 1000:
            raise ConfigError("knowledge.match_chunk must be at most 1000 (the contract's)")


@dataclass(frozen=True)
class PlanConfig:
    """The whole configuration of one planner run."""

    search: SearchConfig = field(default_factory=SearchConfig)
    cp_bo: CpBoConfig = field(default_factory=CpBoConfig)
    mcts_bo: MctsBoConfig = field(default_factory=MctsBoConfig)
    quasi_random: QuasiRandomConfig = field(default_factory=QuasiRandomConfig)
    optuna_tpe: OptunaTpeConfig = field(default_factory=OptunaTpeConfig)
    knowledge: KnowledgeConfig = field(default_factory=KnowledgeConfig)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        return dataclasses.asdict(self)

    def with_overrides(self, overrides: Mapping[str, Any]) -> PlanConfig:
        """A copy with the dotted keys set: text values are parsed by the field's type (`true`,
        `10`, `0.5`), others are checked against it."""
        sections: dict[str, dict[str, Any]] = {}
        for key, value in typed_overrides(overrides).items():
            section, _, name = key.partition(".")
            sections.setdefault(section, {})[name] = value
        return dataclasses.replace(
            self,
            **{
                section: dataclasses.replace(getattr(self, section), **values)
                for section, values in sections.items()
            },
        )


@dataclass(frozen=True)
class Preset:
    """A method that is another method under a fixed configuration."""

    base: str
    overrides: Mapping[str, Any]


PRESETS: Mapping[str, Preset] = {
    "quasi-random-restarts": Preset("quasi-random", {"search.restart_without_knowledge": True}),
    "cp-bo-paper": Preset(
        "cp-bo",
        {
            "cp_bo.prematch": False,
            "cp_bo.lookahead": False,
            "cp_bo.continuations": False,
            "cp_bo.batch": 1,
            "search.outlook_widening": False,
            "search.outlook_selection": False,
            "search.hopeless_widening": False,
            "search.restart_unit": 0,
            "search.restart_redraws": False,
            "knowledge.square_grasps": False,
            "knowledge.grasp_symmetry": False,
            "knowledge.relative_pairs": False,
            "knowledge.periodic_headings": False,
            "knowledge.movable_names": True,
            "knowledge.prior_counts": 0.0,
            "knowledge.follow_found": False,
        },
    ),
}
"""`quasi-random-restarts` is quasi-random given cp-bo's restarts and redraws, nothing else
changed: the strongest baseline without learning. The paper's CP-BO changes only
SAMPLE-NEW-CHILD: types activate when a failure is met, and the tree is plain PW-UCT."""


def base_method(method: str) -> str:
    """The sampler a method runs (itself, unless it is a preset)."""
    preset = PRESETS.get(method)
    return preset.base if preset is not None else method


def method_config(method: str, config: PlanConfig | None = None) -> PlanConfig:
    """`config` (default: the defaults) with the method's preset applied on top: a preset's
    switches are what the method is, so they are not left to the caller."""
    config = config if config is not None else PlanConfig()
    preset = PRESETS.get(method)
    return config.with_overrides(preset.overrides) if preset is not None else config


def known_keys() -> list[str]:
    return [
        f"{section.name}.{f.name}"
        for section in dataclasses.fields(PlanConfig)
        for f in dataclasses.fields(_section_types()[section.name])
    ]


def typed_overrides(overrides: Mapping[str, Any]) -> dict[str, Any]:
    """The dotted overrides with each value as its field's type (`"false"` -> False), sorted by
    key: two spellings of one variant compare equal."""
    out: dict[str, Any] = {}
    for key in sorted(overrides):
        _, _, kind = _field(key)
        out[key] = _typed(key, overrides[key], kind)
    return out


def parse_assignments(items: Iterable[str]) -> dict[str, str]:
    """`["cp_bo.lookahead=false", ...]` as a mapping; keys are checked."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"expected KEY=VALUE, got {item!r}")
        _field(key)
        out[key] = value.strip()
    return out


def read_data_file(path: str | Path, what: str) -> Any:
    """The parsed content of a YAML or JSON file (JSON by its `.json` suffix); a ConfigError
    names `what` the file is and what is wrong with it."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror}") from None
    import yaml

    try:
        return json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as exc:
        kind = "JSON" if path.suffix == ".json" else "YAML"
        raise ConfigError(f"{what} {path} is not valid {kind}: {exc}") from None


def load_file(path: str | Path) -> dict[str, Any]:
    """The dotted overrides of a YAML or JSON file: nested (`cp_bo: {lookahead: false}`) or
    dotted (`cp_bo.lookahead: false`) keys; a file holding a run's recorded `config` works."""
    data = read_data_file(path, "configuration file")
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path} must hold a mapping of configuration keys")
    flat = dict(_flatten(data))
    for key in flat:
        _field(key)
    return flat


def _flatten(data: Mapping[str, Any], prefix: str = "") -> Iterable[tuple[str, Any]]:
    for key, value in data.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping):
            yield from _flatten(value, f"{dotted}.")
        else:
            yield dotted, value


def _section_types() -> dict[str, type]:
    hints = typing.get_type_hints(PlanConfig)
    return {f.name: hints[f.name] for f in dataclasses.fields(PlanConfig)}


def _field(key: str) -> tuple[str, str, type]:
    """The section, field name and type of a dotted key; a typo names the known keys."""
    section, _, name = key.partition(".")
    sections = _section_types()
    kind = typing.get_type_hints(sections[section]).get(name) if section in sections else None
    if kind is None or not name:
        raise ConfigError(f"unknown configuration key {key!r}; known: {', '.join(known_keys())}")
    return section, name, kind


_TRUE = {"true", "1", "yes", "on"}
_FALSE = {"false", "0", "no", "off"}


def _typed(key: str, raw: Any, kind: type) -> Any:
    """`raw` as a value of `kind` (bool, int, float or str); text is parsed."""
    if isinstance(raw, str) and kind is not str:
        text = raw.strip().lower()
        try:
            if kind is bool:
                if text in _TRUE | _FALSE:
                    return text in _TRUE
                raise ValueError
            return kind(text)
        except ValueError:
            raise ConfigError(f"{key} takes a {kind.__name__}, not {raw!r}") from None
    if kind is float and isinstance(raw, int | float) and not isinstance(raw, bool):
        return float(raw)
    if isinstance(raw, kind) and not (kind is int and isinstance(raw, bool)):
        return raw
    raise ConfigError(f"{key} takes a {kind.__name__}, not {raw!r}")

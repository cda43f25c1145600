"""MPF suggestions in the planner's own process, from the service's model snapshots.

A rollout costs little simulation time; a round trip to the service costs more than a rollout
when planners and the fit worker share the CPU. The models themselves are small
(a variational GP is its inducing points and two cached terms), so the planner fetches each
type's current predictor (`POST /v1/kbs/{kb}/models`) and maximises MPF itself, with the same
code (`surrogate.suggest.suggest`) and optimiser settings as the service: this module keeps only
the refresh policy, serves the snapshots as a `ModelSource`, and reads the wire models into the
surrogate library's types at its edge. Between fetches the points this planner posted weigh in
at once (`RecentPoints`), as they would in the service, and so do other planners' points that
the session's live feed brings (`learn`, `planner.knowledge.live`); a model is
fetched anew once its type has new points and `refresh_rollouts` rollouts have passed, and only
if its version changed. Such a refresh runs in the background (the service encodes every
changed fit, which costs it time on a busy machine), and the model in hand, with this planner's own
points, is good until the next one lands. A type with no model yet is fetched at once, unless
this planner is creating it: then it starts from the stated prior on its own points, as the
service would serve it.

Like the service, it keeps the suggestions it served as pending until a point answers them (or
they expire), and pushes new ones away from them: a batch's unused points and other nodes' recent
suggestions keep the tree spread. With live sharing, the session reports them to the service and
hands back the other planners' (`served`, `share`: `planner.knowledge.live.PendingExchange`);
those are pushed away from too, mapped through their types' decision labels onto this request's
variables (another task names its variables its own way).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from contract import models as wire
from contract.models import Constraint, ModelsOut, PendingPoint, SuggestIn, SuggestOut
from planner.config import KnowledgeConfig
from surrogate import snapshot
from surrogate.config import OptimizerConfig, SurrogateConfig
from surrogate.domains import Domain, Value, space_from_json
from surrogate.encoding import encoder_for
from surrogate.pending import PendingBook
from surrogate.predictors import FeasibilityPredictor, Mixture, PriorPredictor, RecentPoints
from surrogate.suggest import ModelSource, SuggestRequest, TypeModel
from surrogate.suggest import suggest as suggest_point

PENDING_KEY = "local"  # the one knowledge base of this process's pending book
# One point moves the evidence by at most log(0.95 / 0.05) = 2.9: a model that put 0.99 on a
# placement that failed is wrong, but not a hundred times as wrong as one that put 0.9 there.
EVIDENCE_CLIP = 0.05
FetchFn = Callable[[list[str], dict[str, str]], ModelsOut]
Shared = tuple[dict[str, Value], tuple[tuple[str, tuple[tuple[str, str], ...]], ...]]


def in_request_terms(shared: list[Shared], constraints: list[Constraint]) -> list[dict[str, Value]]:
    """Other planners' pending points as this request's variables: each type the point and the
    request share maps the point's values, by the type's decision labels, onto the variables
    the request binds them to (a point may so give only some of them)."""
    wanted = {c.type_id for c in constraints}
    out: list[dict[str, Value]] = []
    for x, binds in shared:
        for type_id, bind in binds:
            if type_id not in wanted:
                continue
            for constraint in constraints:
                if constraint.type_id != type_id:
                    continue
                mine = constraint.bind
                point = {mine[label]: x[var] for label, var in bind if var in x and label in mine}
                if point and point not in out:
                    out.append(point)
    return out


def fetch_from(
    source: ModelSource,
    optimizer: OptimizerConfig,
    pending_ttl_s: float = SurrogateConfig().pending_ttl_s,
) -> FetchFn:
    """A fetch answered in this process from `source` (e.g. `surrogate.sources.InMemoryModels`)
    through the same snapshot form the service sends: the planner's models without a server."""

    def fetch(type_ids: list[str], known: dict[str, str]) -> ModelsOut:
        shots = []
        for type_id in dict.fromkeys(type_ids):
            model = source.model(type_id)
            if known.get(type_id) != model.version:
                shots.append(wire.ModelSnapshot(**snapshot.model_to_json(type_id, model)))
        return ModelsOut(
            models=shots, optimizer=optimizer.model_dump(), pending_ttl_s=pending_ttl_s
        )

    return fetch


@dataclass
class Evidence:
    """This run's own points of a type, and how much better the type's fetched model predicted
    them than the stated prior on this run's earlier points did: the log Bayes factor of their
    prequential likelihoods, each point predicted by both before it was known. `weight` is the
    model's posterior probability in a Bayesian average of the two, from `prior`. Kept across
    refetches: a new snapshot holds the points, not how it would have predicted them."""

    prior: float = KnowledgeConfig.model_evidence_prior
    log_ratio: float = 0.0
    points: list[tuple[dict[str, Value], bool]] = field(default_factory=list)

    def observe(self, x: Mapping[str, Value], feasible: bool, p_model: float, p_own: float) -> None:
        p_model, p_own = np.clip([p_model, p_own], EVIDENCE_CLIP, 1.0 - EVIDENCE_CLIP)
        if not feasible:
            p_model, p_own = 1.0 - p_model, 1.0 - p_own
        self.log_ratio += float(np.log(p_model) - np.log(p_own))
        self.points.append((dict(x), feasible))

    @property
    def weight(self) -> float:
        logit = np.log(self.prior) - np.log1p(-self.prior) + self.log_ratio
        return float(1.0 / (1.0 + np.exp(-logit)))


@dataclass(frozen=True)
class PriorSettings:
    """How this planner states the prior of a type without a fit (the `knowledge.prior_*`
    knobs of `KnowledgeConfig`, which say why each exists)."""

    base_rate: bool = KnowledgeConfig.prior_base_rate
    counts: float = KnowledgeConfig.prior_counts
    choice_rates: bool = KnowledgeConfig.prior_choice_rates

    @classmethod
    def of(cls, config: KnowledgeConfig) -> PriorSettings:
        return cls(config.prior_base_rate, config.prior_counts, config.prior_choice_rates)

    def counted(
        self,
        prior: PriorPredictor,
        space: Mapping[str, Domain],
        feasible: np.ndarray | None = None,
        infeasible: np.ndarray | None = None,
    ) -> PriorPredictor:
        """`prior` counting its points (`counts` pseudo-points), with encoded `feasible` `(a, D)`
        and `infeasible` `(b, D)` more of them, centred per categorical choice with
        `choice_rates`."""
        counted = prior.counted(self.counts, feasible, infeasible)
        if not self.choice_rates:
            return counted
        return counted.by_choice(encoder_for(space).choice_rows())


@dataclass
class _Model:
    space: dict[str, Domain]
    fitted: FeasibilityPredictor
    version: str
    n_fitted: int
    fetched_at: int  # rollout
    own: list[tuple[int, dict[str, Value], bool]] = field(default_factory=list)  # (batch, x, ok)
    # Other planners' points since (point id, x, ok): `LocalSurrogates.learn`.
    others: list[tuple[int, dict[str, Value], bool]] = field(default_factory=list)
    born_with: int = 0  # a type this planner created: the poster batch that stores it
    prior: PriorSettings = PriorSettings()
    evidence: Evidence | None = None  # with `KnowledgeConfig.model_evidence`
    _predictor: FeasibilityPredictor | None = None
    _combined: FeasibilityPredictor | None = None
    # `own` and `others` encoded, row for row: both lists only grow, and every new point
    # would otherwise re-encode all of them for the next suggestion.
    _own_z: np.ndarray | None = None
    _others_z: np.ndarray | None = None

    @property
    def fetched(self) -> bool:
        return bool(self.version)

    def predictor(self) -> FeasibilityPredictor:
        """`model()`, averaged with the stated prior on this run's own points by their
        `evidence` when it is kept and there are such points."""
        if self._predictor is None:
            combined = self.model()
            if self.evidence is None or not self.evidence.points:
                self._predictor = combined
            else:
                self._predictor = Mixture(combined, self._own_prior(), self.evidence.weight)
        return self._predictor

    def _own_prior(self) -> PriorPredictor:
        """The stated prior on this run's own points alone: what it knows without the model."""
        assert self.evidence is not None
        return self._stated_prior(*_encoded(self.space, *_by_label(self.evidence.points)))

    def _stated_prior(self, feasible: np.ndarray, infeasible: np.ndarray) -> PriorPredictor:
        prior = PriorPredictor(feasible, infeasible)
        if self.prior.base_rate:
            prior = prior.with_base_rate()
        return self.prior.counted(prior, self.space) if self.prior.counts > 0 else prior

    def model(self) -> FeasibilityPredictor:
        """The fetched predictor with this planner's points since weighed in; for a type this
        planner created and has not fetched yet, the stated prior on its own points (what the
        service serves for a type with so few points)."""
        if self._combined is None:
            self._combined = self._weigh_in()
        return self._combined

    def _weigh_in(self) -> FeasibilityPredictor:
        feasible, infeasible = self._since()
        if not self.fetched:
            return self._stated_prior(feasible, infeasible)
        fitted = self.fitted
        if self.prior.base_rate:
            fitted = with_base_rate(fitted, len(feasible), len(infeasible))
        if self.prior.counts > 0 and (prior := stated_prior(fitted)) is not None:
            # Counted, the points since the service's prior are more of its points.
            return self.prior.counted(prior, self.space, feasible, infeasible)
        if not len(feasible) and not len(infeasible):
            return fitted
        return RecentPoints(fitted, feasible, infeasible)

    def _since(self) -> tuple[np.ndarray, np.ndarray]:
        """The points since the fetch (this run's, then other planners'), encoded: the feasible
        ones `(a, D)`, then the infeasible ones `(b, D)`, each in the order they came."""
        self._own_z = _grown(self._own_z, self.space, [x for _, x, _ in self.own])
        self._others_z = _grown(self._others_z, self.space, [x for _, x, _ in self.others])
        rows = np.vstack([self._own_z, self._others_z])
        ok = np.array([ok for _, _, ok in self.own + self.others], dtype=bool)
        return rows[ok], rows[~ok]

    def add(self, batch: int, x: Mapping[str, Value], feasible: bool) -> None:
        """One of this run's own points; with `evidence`, first scored by the model and by the
        stated prior on this run's earlier points, as each predicted it before it was known."""
        if self.evidence is not None:
            z = encoder_for(self.space).encode_points([dict(x)])
            p_model = float(self.model().proba(z)[0])
            p_own = float(self._own_prior().proba(z)[0])
            self.evidence.observe(x, feasible, p_model, p_own)
        self.own.append((batch, dict(x), feasible))
        self._predictor = self._combined = None


def _by_label(
    points: Iterable[tuple[dict[str, Value], bool]],
) -> tuple[list[dict[str, Value]], list[dict[str, Value]]]:
    """The feasible points' decisions, then the infeasible ones'."""
    feasible: list[dict[str, Value]] = []
    infeasible: list[dict[str, Value]] = []
    for x, ok in points:
        (feasible if ok else infeasible).append(x)
    return feasible, infeasible


def _grown(
    rows: np.ndarray | None, space: Mapping[str, Domain], points: list[dict[str, Value]]
) -> np.ndarray:
    """`rows` (the first points, encoded) with the points after them encoded and appended."""
    encoder = encoder_for(space)
    if rows is None:
        rows = np.zeros((0, encoder.dim))
    if len(points) > len(rows):
        rows = np.vstack([rows, encoder.encode_points(points[len(rows) :])])
    return rows


def _encoded(
    space: Mapping[str, Domain],
    feasible: list[dict[str, Value]],
    infeasible: list[dict[str, Value]],
) -> tuple[np.ndarray, np.ndarray]:
    """Both lists in the type's GP inputs, `(a, D)` and `(b, D)`."""
    encoder = encoder_for(space)
    empty = np.zeros((0, encoder.dim))
    return (
        encoder.encode_points(feasible) if feasible else empty,
        encoder.encode_points(infeasible) if infeasible else empty,
    )


def with_base_rate(
    predictor: FeasibilityPredictor, feasible: int, infeasible: int
) -> FeasibilityPredictor:
    """`predictor` with its stated prior centred on the type's base rate, counting `feasible`
    and `infeasible` points held beside it, if it is one (also under the service's `RecentPoints`,
    whose points count too); a fit is returned as it is. The prior inside `UnseenChoices` keeps
    its centre: it speaks for choices no point has tried, which the type's rate says nothing of."""
    if isinstance(predictor, PriorPredictor):
        return predictor.with_base_rate(feasible, infeasible)
    if isinstance(predictor, RecentPoints):
        base = with_base_rate(
            predictor.base,
            feasible + len(predictor.feasible),
            infeasible + len(predictor.infeasible),
        )
        return predictor if base is predictor.base else dataclasses.replace(predictor, base=base)
    return predictor


def stated_prior(predictor: FeasibilityPredictor) -> PriorPredictor | None:
    """The stated prior a served predictor is, its points since included (the service's
    `RecentPoints` on a prior); None for a fit."""
    if isinstance(predictor, PriorPredictor):
        return predictor
    if isinstance(predictor, RecentPoints) and isinstance(predictor.base, PriorPredictor):
        return predictor.base.counted(
            predictor.base.strength, predictor.feasible, predictor.infeasible
        )
    return None


@dataclass(frozen=True)
class _Fetch:
    """A refresh under way: its answer, the types asked for, and when it was asked."""

    answer: Future[ModelsOut]
    type_ids: list[str]
    rollout: int
    stored: int
    learned: int  # the newest other planner's point taken in when it was asked


class LocalSurrogates:
    def __init__(
        self,
        fetch: FetchFn,
        *,
        background: bool = True,
        refresh_rollouts: int = KnowledgeConfig.refresh_rollouts,
        pending_clock: Callable[[], float] = time.monotonic,
        prior: PriorSettings = PriorSettings(),
        spread_walls: bool = KnowledgeConfig.spread_walls,
        model_evidence: bool = KnowledgeConfig.model_evidence,
        model_evidence_prior: float = KnowledgeConfig.model_evidence_prior,
    ) -> None:
        """`pending_clock` times the pending suggestions' lifetime: a constant one keeps them
        until a point answers them, so that how long a run waits does not change its course."""
        self._fetch = fetch
        self.refresh_rollouts = refresh_rollouts
        self.prior = prior
        self.model_evidence = model_evidence
        self.model_evidence_prior = model_evidence_prior
        self._models: dict[str, _Model] = {}
        self.spread_walls = spread_walls
        self._config = OptimizerConfig(spread_walls=spread_walls)
        self._settings_known = False  # `_config` is the service's (a fetch has been answered)
        # The service's pending lifetime replaces the default with the first fetch.
        self._pending = PendingBook(ttl_s=SurrogateConfig().pending_ttl_s, clock=pending_clock)
        self.fetches = 0
        self.fetch_s = 0.0  # spent waiting for fetches (not the background ones)
        self._executor = (
            ThreadPoolExecutor(1, thread_name_prefix="cpkb-models") if background else None
        )
        self._in_flight: _Fetch | None = None
        self._learned = 0  # the newest point id `learn` has taken in
        self._shared: list[Shared] = []  # other planners' pending suggestions (`share`)
        self.shared_used = 0  # of those, points suggestions here were kept away from

    def adopt(
        self,
        type_id: str,
        space: Mapping[str, wire.CategoricalDomain | wire.ContinuousDomain],
        stored_with: int,
    ) -> bool:
        """Take up a type this planner is creating (its first point goes out in poster batch
        `stored_with`), if the service's optimiser settings are known (from an earlier fetch):
        it guides at once from this planner's own points, without waiting for that batch to be
        stored and fetching the service's model of it (two round trips that cost a guided
        regrasp run about a tenth of its time on a busy machine); the service's model is
        fetched in the background once the batch is stored. False: fetch it as any other."""
        if not self._settings_known:
            return False
        if type_id not in self._models:
            own_space = space_from_json({label: d.model_dump() for label, d in space.items()})
            none = np.zeros((0, encoder_for(own_space).dim))
            self._models[type_id] = _Model(
                own_space,
                PriorPredictor(none, none),
                version="",
                n_fitted=0,
                fetched_at=0,
                born_with=stored_with,
                prior=self.prior,
                evidence=self._evidence(None),
            )
        return True

    def note(self, type_id: str, x: Mapping[str, Value], feasible: bool, batch: int) -> None:
        """A point this planner posted (in poster batch `batch`)."""
        self._pending.answered(PENDING_KEY, type_id, [x])
        model = self._models.get(type_id)
        if model is not None:
            model.add(batch, x, feasible)

    def learn(self, type_id: str, point_id: int, x: Mapping[str, Value], feasible: bool) -> None:
        """A point another planner stored (point `point_id`, newer than the last fetch of its
        type), weighed in until a fetched model holds it; a type not held is left out (its
        model, when fetched, holds the point)."""
        model = self._models.get(type_id)
        if model is not None:
            model.others.append((point_id, dict(x), feasible))
            model._predictor = model._combined = None
            self._learned = max(self._learned, point_id)

    def served(self, limit: int) -> list[PendingPoint]:
        """The newest `limit` suggestions served here that no point has answered yet."""
        entries = [e for e in self._pending.entries(PENDING_KEY) if e.binds][-limit:]
        return [
            PendingPoint(
                x=e.x, binds=[Constraint(type_id=t, bind=dict(bind)) for t, bind in e.binds]
            )
            for e in entries
        ]

    def share(self, others: list[PendingPoint]) -> None:
        """The other planners' pending suggestions now (in place of those shared before)."""
        self._shared = [
            (dict(p.x), tuple((c.type_id, tuple(sorted(c.bind.items()))) for c in p.binds))
            for p in others
        ]

    def suggest(
        self,
        request: SuggestIn,
        rollout: int,
        stored: int,
        hints: Callable[[list[Constraint], set[str]], tuple[list[dict[str, Value]], int]]
        | None = None,
    ) -> SuggestOut:
        """What the service's `suggest` would answer to this planner alone. `stored`: the last
        poster batch the service has taken in (its points are in a fetched model); `hints`:
        points worth scoring, and how many of them (the first) to prefer, given the request's
        constraints and free variables (`planner.knowledge.live.PeerHints.for_request`)."""
        type_ids = list(dict.fromkeys(c.type_id for c in request.constraints))
        self._land()
        missing = [t for t in type_ids if t not in self._models]
        if missing:
            self._apply(self._fetch_now(missing), missing, rollout, stored, self._learned)
        stale = [t for t in type_ids if self._stale(t, rollout, stored)]
        if stale:
            self._refresh(stale, rollout, stored)
        shared = in_request_terms(self._shared, request.constraints) if self._shared else []
        free = set(request.space) - set(request.fixed)
        hinted, preferred = hints(request.constraints, free) if hints is not None else ([], 0)
        answer = suggest_point(
            self,
            SuggestRequest.from_json(request.model_dump()),
            self._pending,
            key=PENDING_KEY,
            config=self._config,
            shared=shared,
            hints=hinted,
            preferred=preferred,
        )
        self.shared_used += len(shared)
        out = answer.to_json()
        out["method"] = f"{answer.method}-local"
        return SuggestOut.model_validate(out)

    def model(self, type_id: str) -> TypeModel:
        """The model in hand (`surrogate.suggest.ModelSource`): the last snapshot, with this
        planner's points since weighed in."""
        held = self._models[type_id]
        n_points = held.n_fitted + len(held.own) + len(held.others)
        return TypeModel(held.space, held.predictor(), held.version, held.n_fitted, n_points)

    def close(self) -> None:
        """Stop the background refresh (one under way is waited for, not applied)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        self._in_flight = None

    def _evidence(self, previous: _Model | None) -> Evidence | None:
        """The evidence a type's new model keeps from the one it replaces (a fresh one for a
        type new here), if this planner weighs evidence."""
        if not self.model_evidence:
            return None
        if previous is not None and previous.evidence is not None:
            return previous.evidence
        return Evidence(prior=self.model_evidence_prior)

    def _stale(self, type_id: str, rollout: int, stored: int) -> bool:
        model = self._models[type_id]
        if not model.fetched:
            return stored >= model.born_with  # the service has the type once its batch is in
        new_points = model.own or model.others
        return bool(new_points) and rollout - model.fetched_at >= self.refresh_rollouts

    def _ask(self, type_ids: list[str]) -> Callable[[], ModelsOut]:
        """The fetch of these types, to be run here or in the background (it reads nothing of
        this object's state when it runs)."""
        known = {t: self._models[t].version for t in type_ids if t in self._models}
        self.fetches += 1
        return lambda: self._fetch(type_ids, known)

    def _fetch_now(self, type_ids: list[str]) -> ModelsOut:
        started = time.perf_counter()
        try:
            return self._ask(type_ids)()
        finally:
            self.fetch_s += time.perf_counter() - started

    def _refresh(self, type_ids: list[str], rollout: int, stored: int) -> None:
        """Fetch newer fits of types in use: in the background if this planner has one (one
        refresh at a time; the types asked for are not stale again until it lands)."""
        if self._executor is None:
            self._apply(self._fetch_now(type_ids), type_ids, rollout, stored, self._learned)
            return
        if self._in_flight is not None:
            return
        for type_id in type_ids:
            self._models[type_id].fetched_at = rollout
        answer = self._executor.submit(self._ask(type_ids))
        self._in_flight = _Fetch(answer, type_ids, rollout, stored, self._learned)

    def _land(self) -> None:
        """Apply a finished background refresh (its error, if it failed, is raised here)."""
        fetch = self._in_flight
        if fetch is None or not fetch.answer.done():
            return
        self._in_flight = None
        result = fetch.answer.result()
        self._apply(result, fetch.type_ids, fetch.rollout, fetch.stored, fetch.learned)

    def _apply(
        self, answer: ModelsOut, type_ids: list[str], rollout: int, stored: int, learned: int
    ) -> None:
        """Take in a fetch's answer; `stored`: the last poster batch the service had taken in
        when it was asked, `learned`: the newest other planner's point taken in then (later
        points stay weighed in on top of the new snapshot)."""
        served = {k: v for k, v in answer.optimizer.items() if k in OptimizerConfig.model_fields}
        self._config = OptimizerConfig(**{**served, "spread_walls": self.spread_walls})
        self._settings_known = True
        self._pending.ttl_s = answer.pending_ttl_s
        for shot in answer.models:
            type_id, model = snapshot.model_from_json(shot.model_dump())
            previous = self._models.get(type_id)
            own = [p for p in previous.own if p[0] > stored] if previous is not None else []
            others = [p for p in previous.others if p[0] > learned] if previous is not None else []
            self._models[type_id] = _Model(
                space=dict(model.space),
                fitted=model.predictor,
                version=model.version,
                n_fitted=model.n_fitted,
                fetched_at=rollout,
                own=own,
                others=others,
                prior=self.prior,
                evidence=self._evidence(previous),
            )
        for type_id in type_ids:
            if type_id not in self._models:
                raise LookupError(f"the service sent no model for type {type_id}")
            self._models[type_id].fetched_at = rollout

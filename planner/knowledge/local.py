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
suggestions keep the tree spread.

A process that suggests here runs its BLAS on one thread (`one_blas_thread`): the planner has one
core, and a suggestion's matrix products (a few hundred candidates by the inducing points) are
too small to gain from a second thread, which, on a core other processes keep busy, the first one
waits for at every product (most of a suggestion's wall time on a loaded machine).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from contract import models as wire
from contract.models import Constraint, ModelsOut, SuggestIn, SuggestOut
from planner.config import KnowledgeConfig
from surrogate import snapshot
from surrogate.config import OptimizerConfig, SurrogateConfig
from surrogate.domains import Domain, Value, space_from_json
from surrogate.encoding import encoder_for
from surrogate.pending import PendingBook
from surrogate.predictors import FeasibilityPredictor, PriorPredictor, RecentPoints
from surrogate.suggest import ModelSource, SuggestRequest, TypeModel
from surrogate.suggest import suggest as suggest_point

PENDING_KEY = "local"  # the one knowledge base of this process's pending book
FetchFn = Callable[[list[str], dict[str, str]], ModelsOut]


def one_blas_thread() -> None:
    """This process's BLAS libraries on one thread from now on (for good: a limit set and
    restored around each suggestion would race with another thread's)."""
    threadpool_limits(limits=1, user_api="blas")


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
    prior_counts: float = KnowledgeConfig.prior_counts
    _combined: FeasibilityPredictor | None = None
    # `own` and `others` encoded, row for row: both lists only grow, and every new point
    # would otherwise re-encode all of them for the next suggestion.
    _own_z: np.ndarray | None = None
    _others_z: np.ndarray | None = None

    @property
    def fetched(self) -> bool:
        return bool(self.version)

    def _stated_prior(self, feasible: np.ndarray, infeasible: np.ndarray) -> PriorPredictor:
        prior = PriorPredictor(feasible, infeasible)
        return prior.counted(self.prior_counts) if self.prior_counts > 0 else prior

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
        if self.prior_counts > 0 and (prior := stated_prior(fitted)) is not None:
            # Counted, the points since the service's prior are more of its points.
            return prior.counted(self.prior_counts, feasible, infeasible)
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
        """One of this run's own points."""
        self.own.append((batch, dict(x), feasible))
        self._combined = None


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
        prior_counts: float = KnowledgeConfig.prior_counts,
        spread_walls: bool = KnowledgeConfig.spread_walls,
    ) -> None:
        """`pending_clock` times the pending suggestions' lifetime: a constant one keeps them
        until a point answers them, so that how long a run waits does not change its course."""
        one_blas_thread()
        self._fetch = fetch
        self.refresh_rollouts = refresh_rollouts
        self.prior_counts = prior_counts
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
                prior_counts=self.prior_counts,
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
            model._combined = None
            self._learned = max(self._learned, point_id)

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
        free = set(request.space) - set(request.fixed)
        hinted, preferred = hints(request.constraints, free) if hints is not None else ([], 0)
        answer = suggest_point(
            self,
            SuggestRequest.from_json(request.model_dump()),
            self._pending,
            key=PENDING_KEY,
            config=self._config,
            hints=hinted,
            preferred=preferred,
        )
        out = answer.to_json()
        out["method"] = f"{answer.method}-local"
        return SuggestOut.model_validate(out)

    def model(self, type_id: str) -> TypeModel:
        """The model in hand (`surrogate.suggest.ModelSource`): the last snapshot, with this
        planner's points since weighed in."""
        held = self._models[type_id]
        n_points = held.n_fitted + len(held.own) + len(held.others)
        return TypeModel(held.space, held.model(), held.version, held.n_fitted, n_points)

    def close(self) -> None:
        """Stop the background refresh (one under way is waited for, not applied)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        self._in_flight = None

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
                prior_counts=self.prior_counts,
            )
        for type_id in type_ids:
            if type_id not in self._models:
                raise LookupError(f"the service sent no model for type {type_id}")
            self._models[type_id].fetched_at = rollout

"""The per-type surrogate engine of the service.

One entry per (kb, type): the type's points (encoded, loaded incrementally), its latest fit and
the predictor requests use. Fits never run on the request path: new points (the `points_added`
hook) or a periodic freshness check put the type on a queue; one coordinator thread takes types
off it one at a time, loads the new points, and fits with a warm start from the previous fit in
a single fit worker (a child process by default). A type is queued once however often it is
asked for (its next fit takes in all its new points), and the queue serves the types a request
is waiting on first, then the types without a fit, then the rest.

A new type does not wait for that queue: while it has no background fit and at most
`instant_fit_points` points, a second thread of the service's own process gives it a short fit
at once (`instant_fit_iters` steps, a fraction of a second at that size). With
`instant_refit_factor`, so does a type whose fit holds fewer than 1/factor of its points, warm
from that fit: with many planners at once the queue lags, and a model of half the points
misleads them all meanwhile. A background fit never warm-starts from an instant one (it starts
from the previous background fit): whether an instant fit landed before the background fit
began is a matter of timing, and a fit must be a function of the points alone for
`--deterministic` runs to repeat. A request always answers with the latest finished fit (or
the stated prior of `surrogate.models.PriorPredictor` until there is one).

Replicas of the service on one database share their fits (`server.surrogates.shared`): before
fitting, the coordinator loads a stored fit that covers the type's points, and fits only under
the type's claim; a type first seen here starts from the stored fit. The pending book is the
database's (`server.surrogates.pending_db`) when `pending_in_database`. An instant fit stays in
its replica: it is never stored, and a stored fit of as many points replaces it.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from contract.models import SurrogateState
from server.db import Store
from server.errors import NotFound
from server.services.types import TrainingPoints, load_training_points
from server.settings import ServiceSurrogateConfig
from server.surrogates.pending_db import DatabasePendingBook
from server.surrogates.shared import FitShare
from server.surrogates.worker import ChildProcessFitter, Fitter, ThreadFitter, WorkerDied
from surrogate.domains import Domain, space_from_json
from surrogate.encoding import SpaceEncoder, encoder_for
from surrogate.models import MIN_POINTS, Fit, fit_classifier, use_threads, warm_up
from surrogate.pending import Pending, PendingBook
from surrogate.predictors import FeasibilityPredictor
from surrogate.sources import Seen, needs_model, prior, seen_choices, served_predictor
from surrogate.suggest import TypeModel

log = logging.getLogger("cpkb.surrogates")
Key = tuple[str, str]
ASKED, FIRST, REFRESH = 0, 1, 2  # queue priorities, the lowest served first
_WARMED = threading.Event()  # torch's first-fit cost is paid once per process
_WARM_LOCK = threading.Lock()
FIT_THREADS = 1  # the fit worker's threads: the other core is the server's
REQUEST_THREADS = 1  # BLAS's threads in the service's process, whose requests run in parallel


@dataclass
class KbGauges:
    backlog: int = 0  # types queued or fitting
    unfitted_points: int = 0  # loaded points the served models were not fitted on
    stale_model_age_s: float = 0.0  # age of the oldest fit among types with such points


@dataclass
class _Entry:
    space: dict[str, Domain]
    encoder: SpaceEncoder
    z: np.ndarray
    y: np.ndarray
    last_point_id: int | None
    predictor: FeasibilityPredictor
    origin: tuple[int, datetime]  # the type's row (TrainingPoints.origin)
    fit: Fit | None = None
    n_fitted: int = 0
    status: str = "prior"
    checked_at: float = 0.0
    fitted_at: datetime | None = None
    error: str | None = None
    merging: threading.Lock = field(default_factory=threading.Lock, repr=False)
    seen: Seen = ()  # the fit's categorical choices (UnseenChoices)
    instant: bool = False  # the fit is the instant lane's: the background fit is still to come
    background: Fit | None = None  # the latest background (or stored) fit: the next one's start

    @property
    def n_points(self) -> int:
        return len(self.y)


class SurrogateEngine:
    def __init__(
        self,
        store: Store,
        config: ServiceSurrogateConfig | None = None,
        *,
        pending_in_database: bool = False,
        replica: str | None = None,
    ) -> None:
        """`pending_in_database`: the pending book is the database's, shared by the replicas;
        `replica`: the name that marks the fits this one stores (default host:pid)."""
        self.store = store
        self.config = config or ServiceSurrogateConfig()
        ttl = self.config.pending_ttl_s
        self.pending: Pending = (
            DatabasePendingBook(store, ttl) if pending_in_database else PendingBook(ttl)
        )
        replica = replica or f"{socket.gethostname()}:{os.getpid()}"
        self.shared = FitShare(store, replica) if self.config.share_fits else None
        self._entries: dict[Key, _Entry] = {}
        self._queue: dict[Key, int] = {}  # type -> priority, in the order queued
        self._busy: Key | None = None
        self._first: dict[Key, None] = {}  # types waiting for an instant first model
        self._first_busy: Key | None = None
        self._cond = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._first_thread: threading.Thread | None = None
        self._fitter: Fitter | None = None
        self.fits = 0
        self.adopted = 0  # fits of another replica (or an earlier run) loaded, not fitted

    # --- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Start the coordinator (idempotent) and queue the most recently updated types: their
        fits warm the fit worker up at start. The worker itself (and its warm-up, several
        seconds) starts with the first fit, so an empty service pays nothing."""
        self._start(after_stop=True)

    def _start(self, *, after_stop: bool) -> None:
        """`after_stop=False` (a fit queued by a request): not once `stop` has run, for a
        restart would clear the stop the old threads have yet to see, and `stop` would wait
        for them to its timeout while the new ones outlive the server."""
        with self._cond:
            if self._thread is not None or (self._stopping and not after_stop):
                return
            self._stopping = False
            use_threads(REQUEST_THREADS)
            self._thread = threading.Thread(target=self._run, name="cpkb-surrogates", daemon=True)
            self._thread.start()
            if self.config.instant_fit_points > 0:
                self._first_thread = threading.Thread(
                    target=self._run_first, name="cpkb-first-models", daemon=True
                )
                self._first_thread.start()
        self._prefit()

    def stop(self) -> None:
        """Stop without waiting for a fit in flight: it is of no use to a stopping server, so
        its worker is ended and the coordinator leaves at once."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
            thread, self._thread = self._thread, None
            first, self._first_thread = self._first_thread, None
            fitter, self._fitter = self._fitter, None
        if fitter is not None:
            fitter.terminate()
        for t in (thread, first):
            if t is not None:
                t.join(timeout=30)

    def _new_fitter(self) -> Fitter:
        if not self.config.fit_process:
            return ThreadFitter()
        try:
            return ChildProcessFitter(FIT_THREADS)
        except (RuntimeError, OSError) as exc:
            # e.g. spawn refused inside an unguarded `__main__` script: fit in a thread instead.
            log.warning("cannot start the fit process (%s); fitting in a thread", exc)
            return ThreadFitter()

    def _fitter_for_next_fit(self, replacing: Fitter | None = None) -> Fitter:
        """The fitter to use (a new one in place of `replacing`). Only the coordinator thread
        creates one; every swap happens under the engine's lock, so that `stop` always ends
        the fitter that is in use."""
        with self._cond:
            if self._stopping:
                raise RuntimeError("the surrogate engine is stopping")
            if self._fitter is not None and self._fitter is not replacing:
                return self._fitter
        fresh = self._new_fitter()  # outside the lock: starting a process takes a while
        with self._cond:
            stale, self._fitter = self._fitter, fresh
            stopping = self._stopping
            if stopping:
                self._fitter = None
        if stale is not None:
            stale.terminate()
        if stopping:
            fresh.terminate()
            raise RuntimeError("the surrogate engine is stopping")
        return fresh

    def _prefit(self) -> None:
        from server.services.kbs import list_kbs
        from server.services.types import list_types

        if self.config.prefit_types <= 0:
            return
        recent = [
            (str(t.updated_at), kb.name, t.type_id)
            for kb in list_kbs(self.store)
            for t in list_types(self.store, kb.name)
            if t.n_points >= MIN_POINTS
        ]
        recent.sort(reverse=True)
        for _, kb, type_id in recent[: self.config.prefit_types]:
            self._enqueue((kb, type_id))

    # --- hooks and request path ----------------------------------------------------------
    def notify(self, kb: str, type_ids: frozenset[str]) -> None:
        """`points_added` hook: queue the types (only the cheap part runs on the request), and
        those that may want an instant first model for that lane too."""
        for type_id in sorted(type_ids):
            key = (kb, type_id)
            self._enqueue(key)
            with self._cond:
                entry = self._entries.get(key)
                if self._first_thread is not None and (
                    entry is None
                    or entry.fit is None
                    or (
                        (entry.instant or self.config.instant_refit_factor > 0)
                        and entry.n_points <= self.config.instant_fit_points
                    )
                ):
                    self._first[key] = None
                    self._cond.notify_all()

    def forget(self, kb: str) -> None:
        """`kb_deleted` hook: drop the knowledge base's models and queued fits, so that one
        created again under its name learns from its own points only."""
        with self._cond:
            for key in [k for k in self._entries if k[0] == kb]:
                del self._entries[key]
            for queue in (self._queue, self._first):
                for key in [k for k in queue if k[0] == kb]:
                    del queue[key]

    def source(self, kb: str) -> KbModels:
        """The models of one knowledge base, as `surrogate.suggest` asks for them."""
        return KbModels(self, kb)

    def model(self, kb: str, type_id: str) -> TypeModel:
        """The type's space and current predictor (NotFound if unknown): the latest fit, with
        the points that arrived since weighed in. The first request for a type this process has
        not seen loads its points here (one fast query)."""
        key = (kb, type_id)
        with self._cond:
            entry = self._entries.get(key)
            if key in self._queue:
                self._queue[key] = ASKED  # a planner waits on it: fit it next
        if entry is None:
            entry = self._load_new(key)
        elif time.monotonic() - entry.checked_at > self.config.refresh_s:
            entry = self._catch_up(key, entry)
        with self._cond:
            predictor, z, y, n_fitted = entry.predictor, entry.z, entry.y, entry.n_fitted
            fitted = entry.fit is not None and entry.status == "ready"
            seen, instant = entry.seen, entry.instant
        predictor = served_predictor(predictor, z, y, n_fitted, seen if fitted else ())
        # An instant fit and the background fit of as many points are two versions: a planner
        # holding the short fit fetches the full one when it lands.
        version = f"{n_fitted}-instant" if instant else str(n_fitted)
        return TypeModel(entry.space, predictor, version, n_fitted, len(y))

    def _catch_up(self, key: Key, entry: _Entry) -> _Entry:
        """A type in use whose points are older than `refresh_s`: load the new points (one
        indexed query). A type without both classes gets its stated prior at once, here (a
        prior is a distance computation, not a fit: it must not wait behind other knowledge
        bases' fits); one that needs a model goes to the front of the fit queue, since a
        planner is using it now."""
        # Another thread may be merging this type (the instant lane, woken by the same post):
        # wait for it, a query's time, rather than answer without the points it is loading.
        with entry.merging:
            new = load_training_points(self.store, *key, after_point_id=entry.last_point_id)
            entry = self._merge(key, entry, new)
        if entry.n_fitted == entry.n_points:
            return entry
        if needs_model(entry.y):
            self._enqueue(key, ASKED)
            return entry
        with self._cond:
            entry.predictor = prior(entry.z, entry.y)
            entry.n_fitted, entry.status = entry.n_points, "prior"
        return entry

    def predict(self, kb: str, type_id: str, xs: list[dict]) -> list[float]:
        """P(feasible) of `xs` (decision label -> value) under the type's current model."""
        handle = self.model(kb, type_id)
        z = encoder_for(handle.space).encode_points(xs)
        return [float(p) for p in handle.predictor.proba(z)]

    def predict_with_uncertainty(
        self, kb: str, type_id: str, xs: list[dict]
    ) -> tuple[list[float], list[float]]:
        """For the dashboard, beside `predict` (not on the wire): P(feasible) of `xs` and how
        unsure the same model is there, its latent posterior sd over the prior's
        (`FeasibilityPredictor.uncertainty`); one model and one encoding for both."""
        handle = self.model(kb, type_id)
        z = encoder_for(handle.space).encode_points(xs)
        p, sd = handle.predictor.proba(z), handle.predictor.uncertainty(z)
        return [float(v) for v in p], [float(v) for v in sd]

    def state(self, kb: str, type_id: str) -> SurrogateState | None:
        with self._cond:
            entry = self._entries.get((kb, type_id))
            key = (kb, type_id)
            queued = (
                key in self._queue or key in self._first or key in (self._busy, self._first_busy)
            )
        if entry is None:
            return SurrogateState(status="queued" if queued else "not loaded")
        fit = entry.fit
        status = "fitting" if queued and entry.status != "error" else entry.status
        return SurrogateState(
            status=status,
            version=entry.n_fitted,
            n_fitted=entry.n_fitted,
            lengthscales=fit.lengthscales if fit else None,
            fit_seconds=fit.fit_seconds if fit else None,
            train_accuracy=fit.train_accuracy if fit else None,
            kind=fit.kind if fit else "prior",
            iterations=fit.iterations if fit else 0,
            n_points=entry.n_points,
            fitted_at=entry.fitted_at,
            error=entry.error,
        )

    def gauges(self) -> dict[str, KbGauges]:
        """Per knowledge base: types waiting for a fit, points the served models were not
        fitted on, and how old the latest fit is of the stalest type that lags (for /metrics)."""
        now = datetime.now(UTC)
        out: dict[str, KbGauges] = {}
        with self._cond:
            waiting = [*self._queue, *([self._busy] if self._busy is not None else [])]
            for kb, _ in waiting:
                out.setdefault(kb, KbGauges()).backlog += 1
            for (kb, _), entry in self._entries.items():
                lag = entry.n_points - entry.n_fitted
                if lag <= 0:
                    continue
                gauge = out.setdefault(kb, KbGauges())
                gauge.unfitted_points += lag
                if entry.fitted_at is not None:
                    age = (now - entry.fitted_at).total_seconds()
                    gauge.stale_model_age_s = max(gauge.stale_model_age_s, age)
        return out

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until no type is queued or fitting (tests, benchmarks); False on timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._queue or self._first or self._busy or self._first_busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(timeout=min(left, 0.1))
        return True

    # --- internals ---------------------------------------------------------------------
    def _enqueue(self, key: Key, priority: int | None = None) -> None:
        """Queue a type for a refresh, once: queued again, it keeps its place and the higher of
        its priorities (by default FIRST for a type without a fit, else REFRESH)."""
        with self._cond:
            if priority is None:
                entry = self._entries.get(key)
                priority = FIRST if entry is None or entry.fit is None else REFRESH
            self._queue[key] = min(priority, self._queue.get(key, priority))
            self._cond.notify_all()
        if self._thread is None:
            self._start(after_stop=False)

    def _load_new(self, key: Key, *, queue: bool = True) -> _Entry:
        """A type's entry from all its points, queued for a fit if it needs one (unless the
        caller is the coordinator about to fit it)."""
        points = load_training_points(self.store, *key)
        space = space_from_json({label: d.model_dump() for label, d in points.space.items()})
        encoder = encoder_for(space)
        z = encoder.encode_points(points.x) if points.x else np.zeros((0, encoder.dim))
        y = np.asarray(points.feasible, dtype=bool)
        entry = _Entry(space, encoder, z, y, points.last_point_id, prior(z, y), points.origin)
        if not needs_model(y):
            # The stated prior holds every point: none is recent, or it would count twice.
            entry.n_fitted = entry.n_points
        entry.checked_at = time.monotonic()
        with self._cond:
            stored = self._entries.setdefault(key, entry)
        if stored is entry and needs_model(entry.y):
            self._adopt_stored(key, entry)
        if queue and needs_model(stored.y) and stored.n_fitted < stored.n_points:
            self._enqueue(key)
        return stored

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._stopping:
                    self._cond.wait()
                if self._stopping:
                    return
                key = min(self._queue, key=self._queue.__getitem__)  # the first of the most urgent
                del self._queue[key]
                self._busy = key
            try:
                self._refresh(key)
            except NotFound:
                with self._cond:
                    self._entries.pop(key, None)
            except Exception as exc:  # a failed fit must not stop the worker
                if self._stopping:
                    return
                log.exception("surrogate fit failed for %s/%s", *key)
                self._mark_error(key, exc)
            finally:
                with self._cond:
                    self._busy = None
                    self._cond.notify_all()

    def _refresh(self, key: Key) -> None:
        with self._cond:
            entry = self._entries.get(key)
        if entry is None:
            entry = self._load_new(key, queue=False)
        else:
            with entry.merging:
                new = load_training_points(self.store, *key, after_point_id=entry.last_point_id)
                entry = self._merge(key, entry, new)
        if entry.n_fitted == entry.n_points and not entry.instant:
            return  # nothing new (after an error: retried when points arrive)
        if not needs_model(entry.y):
            with self._cond:
                entry.predictor = prior(entry.z, entry.y)
                entry.n_fitted, entry.status = entry.n_points, "prior"
            return
        if self._adopt_stored(key, entry):
            return
        with self._claim(entry) as mine:
            if not mine:
                self._retry_later(key)
                return
            if self._adopt_stored(key, entry):  # it landed between the look and the claim
                return
            with self._cond:  # the instant lane may install a fit meanwhile
                z, y, n = entry.z, entry.y, entry.n_points
                warm = entry.background  # see the module's docstring
            fit = self._fit(z, y, warm)
            if self.shared is not None:
                self.shared.save(entry.origin[0], fit, entry.origin[1])
        self.fits += 1
        _record_fit(fit.fit_seconds, n)
        log.info(
            "fitted %s/%s version %d in %.2f s",
            *key,
            n,
            fit.fit_seconds,
            extra={"kb": key[0], "type_id": key[1], "version": n, "fit_kind": fit.kind},
        )
        self._install(entry, fit, n)

    def _install(self, entry: _Entry, fit: Fit, n: int) -> None:
        """Serve `fit` as the type's model from here on; `n` is its version."""
        seen = seen_choices(entry.encoder, entry.z[:n])
        with self._cond:
            entry.fit, entry.predictor, entry.seen = fit, fit.predictor, seen
            entry.n_fitted, entry.status, entry.error = n, "ready", None
            entry.fitted_at, entry.instant, entry.background = datetime.now(UTC), False, fit

    def _claim(self, entry: _Entry) -> AbstractContextManager[bool]:
        return self.shared.claim(entry.origin[0]) if self.shared is not None else nullcontext(True)

    def _adopt_stored(self, key: Key, entry: _Entry) -> bool:
        """Serve the stored fit if it is newer than the entry's; True if it covers every point
        the entry holds (nothing is left to fit)."""
        if self.shared is None:
            return False
        than = entry.n_fitted - 1 if entry.instant else entry.n_fitted  # a fit of as many wins
        stored = self.shared.newer(entry.origin[0], than)
        if stored is None:
            return entry.n_fitted >= entry.n_points and not entry.instant
        # A fit of more points than this replica has loaded serves as a fit of those it holds;
        # it is loaded again once the rest are here.
        self._install(entry, stored.fit, min(stored.fit.n_fitted, entry.n_points))
        with self._cond:
            entry.fitted_at = stored.fitted_at
        self.adopted += 1
        _record_adopted()
        log.info(
            "loaded %s/%s version %d fitted by %s",
            *key,
            stored.fit.n_fitted,
            stored.fitted_by,
            extra={"kb": key[0], "type_id": key[1], "version": stored.fit.n_fitted},
        )
        return stored.fit.n_fitted >= entry.n_points

    def _retry_later(self, key: Key) -> None:
        """Another replica is fitting the type: look again once it may have saved its fit."""

        def again() -> None:
            if not self._stopping:
                self._enqueue(key)

        timer = threading.Timer(self.config.claim_retry_s, again)
        timer.daemon = True
        timer.start()

    def _fit(self, z: np.ndarray, y: np.ndarray, warm: Fit | None) -> Fit:
        config = self.config
        args = (
            z,
            y,
            0,
            warm,
            config.max_inducing,
            config.max_fit_points,
            config.balance_classes,
        )
        fitter = self._fitter_for_next_fit()
        try:
            return fitter.fit(*args)
        except WorkerDied:
            if self._stopping:
                raise
            log.warning("fit worker died; starting a new one")
            return self._fitter_for_next_fit(replacing=fitter).fit(*args)

    def _run_first(self) -> None:
        """The instant lane: pays this process's first-fit cost at once (once per process),
        then fits each new type it is given (`_first_model`) until the engine stops."""
        use_threads(REQUEST_THREADS)  # OpenMP's count is the calling thread's
        with _WARM_LOCK:
            if not _WARMED.is_set():
                warm_up()
                _WARMED.set()
        while True:
            with self._cond:
                while not self._first and not self._stopping:
                    self._cond.wait()
                if self._stopping:
                    return
                key = next(iter(self._first))
                del self._first[key]
                self._first_busy = key
            try:
                self._first_model(key)
            except NotFound:
                pass  # deleted meanwhile: the coordinator drops its entry
            except Exception:  # the background fit still comes; this lane must go on
                log.exception("instant first model failed for %s/%s", *key)
            finally:
                with self._cond:
                    self._first_busy = None
                    self._cond.notify_all()

    def _first_model(self, key: Key) -> None:
        """A short fit, here and now, of a type with few enough points that has no background
        fit yet (or one that lags `instant_refit_factor` times behind its points); a background
        fit of as many points that lands first wins, and one replaces this one when it lands."""
        with self._cond:
            entry = self._entries.get(key)
        if entry is None:
            entry = self._load_new(key)
        else:
            with entry.merging:
                new = load_training_points(self.store, *key, after_point_id=entry.last_point_id)
                entry = self._merge(key, entry, new)
        with self._cond:
            z, y, n, fit, instant = entry.z, entry.y, entry.n_points, entry.fit, entry.instant
        config = self.config
        if n > config.instant_fit_points or not needs_model(y) or entry.n_fitted >= n:
            return
        refit = config.instant_refit_factor > 0 and n > config.instant_refit_factor * entry.n_fitted
        if fit is not None and not instant and not refit:
            return
        first = fit_classifier(
            z[:n],
            y[:n],
            seed=0,
            warm=fit,
            max_inducing=config.max_inducing,
            max_points=config.max_fit_points,
            max_iters=config.instant_fit_iters,
            warm_iters=config.instant_fit_iters // 3,
            balance=config.balance_classes,
        )
        seen = seen_choices(entry.encoder, z[:n])
        with self._cond:
            current = entry.fit is None or entry.instant or refit
            if current and n > entry.n_fitted and self._entries.get(key) is entry:
                entry.fit, entry.predictor, entry.seen = first, first.predictor, seen
                entry.n_fitted, entry.status, entry.error = n, "ready", None
                entry.fitted_at, entry.instant = datetime.now(UTC), True

    def _merge(self, key: Key, entry: _Entry, new: TrainingPoints) -> _Entry:
        if new.origin != entry.origin:  # deleted and created again (elsewhere): start afresh
            with self._cond:
                if self._entries.get(key) is entry:
                    del self._entries[key]
            return self._load_new(key)
        entry.checked_at = time.monotonic()
        if not new.x:
            return entry
        z_new = entry.encoder.encode_points(new.x)
        y_new = np.asarray(new.feasible, dtype=bool)
        with self._cond:
            entry.z = np.vstack([entry.z, z_new])
            entry.y = np.concatenate([entry.y, y_new])
            entry.last_point_id = new.last_point_id
        self.pending.answered(key[0], key[1], new.x)
        return entry

    def _mark_error(self, key: Key, exc: Exception) -> None:
        with self._cond:
            entry = self._entries.get(key)
            if entry is not None:
                entry.status, entry.error = "error", f"{type(exc).__name__}: {exc}"
                entry.n_fitted = entry.n_points
        _record_fit(0.0, 0, ok=False)


def _record_adopted() -> None:
    try:
        from server.observability import record_fit_adopted
    except ImportError:
        return
    record_fit_adopted()


def _record_fit(seconds: float, n_points: int, ok: bool = True) -> None:
    try:
        from server.observability import record_fit
    except ImportError:
        return
    record_fit(seconds, n_points, ok)


class KbModels:
    """The `surrogate.suggest.ModelSource` of one knowledge base of an engine."""

    def __init__(self, engine: SurrogateEngine, kb: str) -> None:
        self.engine = engine
        self.kb = kb

    def model(self, type_id: str) -> TypeModel:
        return self.engine.model(self.kb, type_id)

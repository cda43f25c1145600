"""The per-type surrogate engine of the service.

One entry per (kb, type): the type's points (encoded, loaded incrementally), its latest fit and
the predictor requests use. Fits never run on the request path: new points (the `points_added`
hook) or a periodic freshness check put the type on a queue; one coordinator thread takes types
off it one at a time, loads the new points, and fits with a warm start from the previous fit in
a single fit worker (a child process by default). A request always answers with the latest
finished fit (or the stated prior of `surrogate.models.PriorPredictor` until there is one).
"""

from __future__ import annotations

import logging
import multiprocessing
import threading
import time
from collections import OrderedDict
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from client.models import SurrogateState
from server.db import Store
from server.errors import NotFound
from server.services.types import TrainingPoints, load_training_points
from server.surrogates import fitproc
from surrogate.encoding import Domain, SpaceEncoder
from surrogate.models import (
    MIN_POINTS,
    FeasibilityPredictor,
    Fit,
    PriorPredictor,
    RecentPoints,
    UnseenChoices,
)
from surrogate.optimize import OptimizerConfig
from surrogate.pending import PendingBook

log = logging.getLogger("cpkb.surrogates")
Key = tuple[str, str]


@dataclass(frozen=True)
class EngineConfig:
    fit_in_process: bool = True
    fit_threads: int = 1
    max_inducing: int = 128
    refresh_s: float = 0.5
    pending_ttl_s: float = 30.0
    prefit_types: int = 16
    optimizer: OptimizerConfig = field(default_factory=OptimizerConfig)


@dataclass(frozen=True)
class ModelHandle:
    """What a request needs of one type: its decision space and current predictor (the latest
    fit, with the points that arrived since weighed in: `surrogate.models.RecentPoints`)."""

    space: dict[str, Domain]
    predictor: FeasibilityPredictor
    n_points: int
    n_fitted: int


@dataclass
class _Entry:
    space: dict[str, Domain]
    encoder: SpaceEncoder
    z: np.ndarray
    y: np.ndarray
    last_point_id: int | None
    predictor: FeasibilityPredictor
    fit: Fit | None = None
    n_fitted: int = 0
    status: str = "prior"
    checked_at: float = 0.0
    fitted_at: datetime | None = None
    error: str | None = None
    merging: threading.Lock = field(default_factory=threading.Lock, repr=False)
    seen: tuple[tuple[slice, np.ndarray], ...] = ()  # the fit's categorical choices (UnseenChoices)

    @property
    def n_points(self) -> int:
        return len(self.y)


def _prior(z: np.ndarray, y: np.ndarray) -> PriorPredictor:
    return PriorPredictor(feasible=z[y], infeasible=z[~y])


def _seen_choices(encoder: SpaceEncoder, z: np.ndarray) -> tuple[tuple[slice, np.ndarray], ...]:
    """Per categorical variable of the encoding: its columns and the distinct rows of `z` there
    (the choices the fitted points hold)."""
    seen = []
    for var in encoder.vars:
        if var.table is not None:
            columns = slice(var.start, var.start + var.width)
            seen.append((columns, np.unique(z[:, columns], axis=0)))
    return tuple(seen)


def _needs_model(y: np.ndarray) -> bool:
    return len(y) >= MIN_POINTS and bool(y.any()) and not bool(y.all())


class SurrogateEngine:
    def __init__(self, store: Store, config: EngineConfig | None = None) -> None:
        self.store = store
        self.config = config or EngineConfig()
        self.pending = PendingBook(self.config.pending_ttl_s)
        self._entries: dict[Key, _Entry] = {}
        self._queue: OrderedDict[Key, None] = OrderedDict()
        self._busy: Key | None = None
        self._cond = threading.Condition()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._executor: Executor | None = None
        self.fits = 0

    # --- lifecycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Start the coordinator (idempotent) and queue the most recently updated types: their
        fits warm the fit worker up at start. The worker itself (and its warm-up, several
        seconds) starts with the first fit, so an empty service pays nothing."""
        with self._cond:
            if self._thread is not None:
                return
            self._stopping = False
            self._thread = threading.Thread(target=self._run, name="cpkb-surrogates", daemon=True)
            self._thread.start()
        self._prefit()

    def stop(self) -> None:
        """Stop without waiting for a fit in flight: it is of no use to a stopping server, so
        its worker is ended and the coordinator leaves at once."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
            thread, self._thread = self._thread, None
            executor, self._executor = self._executor, None
        if isinstance(executor, ProcessPoolExecutor):
            workers = list((getattr(executor, "_processes", None) or {}).values())
            executor.shutdown(wait=False, cancel_futures=True)
            for worker in workers:
                worker.terminate()
            for worker in workers:
                worker.join(timeout=5)
        elif executor is not None:
            executor.shutdown(wait=False, cancel_futures=True)
        if thread is not None:
            thread.join(timeout=30)

    def _new_executor(self, in_process: bool | None = None) -> Executor:
        if self.config.fit_in_process if in_process is None else in_process:
            return ProcessPoolExecutor(
                max_workers=1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=fitproc.init_worker,
                initargs=(self.config.fit_threads,),
            )
        executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cpkb-fit")
        executor.submit(fitproc.warm_up)  # runs before the first fit, in the same thread
        return executor

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
        """`points_added` hook: queue the types (only the cheap part runs on the request)."""
        for type_id in sorted(type_ids):
            self._enqueue((kb, type_id))

    def model(self, kb: str, type_id: str) -> ModelHandle:
        """The type's space and current predictor (NotFound if unknown). The first request for
        a type this process has not seen loads its points here (one fast query)."""
        key = (kb, type_id)
        with self._cond:
            entry = self._entries.get(key)
        if entry is None:
            entry = self._load_new(key)
        elif time.monotonic() - entry.checked_at > self.config.refresh_s:
            self._catch_up(key, entry)
        with self._cond:
            predictor, z, y, n_fitted = entry.predictor, entry.z, entry.y, entry.n_fitted
            fitted = entry.fit is not None and entry.status == "ready"
            seen = entry.seen
        if n_fitted < len(y):
            recent, labels = z[n_fitted:], y[n_fitted:]
            predictor = RecentPoints(predictor, recent[labels], recent[~labels])
        if fitted and seen:
            predictor = UnseenChoices(predictor, _prior(z, y), seen)
        return ModelHandle(entry.space, predictor, len(y), n_fitted)

    def _catch_up(self, key: Key, entry: _Entry) -> None:
        """A type in use whose points are older than `refresh_s`: load the new points (one
        indexed query). A type without both classes gets its stated prior at once, here (a
        prior is a distance computation, not a fit: it must not wait behind other knowledge
        bases' fits); one that needs a model goes to the front of the fit queue, since a
        planner is using it now."""
        if not entry.merging.acquire(blocking=False):
            return  # another thread is catching this type up
        try:
            new = load_training_points(self.store, *key, after_point_id=entry.last_point_id)
            self._merge(key, entry, new)
        finally:
            entry.merging.release()
        if entry.n_fitted == entry.n_points:
            return
        if _needs_model(entry.y):
            self._enqueue(key, urgent=True)
            return
        with self._cond:
            entry.predictor = _prior(entry.z, entry.y)
            entry.n_fitted, entry.status = entry.n_points, "prior"

    def predict(self, kb: str, type_id: str, xs: list[dict]) -> list[float]:
        """P(feasible) of `xs` (decision label -> value) under the type's current model."""
        handle = self.model(kb, type_id)
        z = SpaceEncoder(handle.space).encode_points(xs)
        return [float(p) for p in handle.predictor.proba(z)]

    def state(self, kb: str, type_id: str) -> SurrogateState | None:
        with self._cond:
            entry = self._entries.get((kb, type_id))
            queued = (kb, type_id) in self._queue or self._busy == (kb, type_id)
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

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until no type is queued or fitting (tests, benchmarks); False on timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._queue or self._busy is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(timeout=min(left, 0.1))
        return True

    # --- internals ---------------------------------------------------------------------
    def _enqueue(self, key: Key, *, urgent: bool = False) -> None:
        """Queue a type for a refresh; an `urgent` one (requested right now) goes first."""
        with self._cond:
            self._queue[key] = None
            if urgent:
                self._queue.move_to_end(key, last=False)
            self._cond.notify_all()
        if self._thread is None:
            self.start()

    def _load_new(self, key: Key) -> _Entry:
        points = load_training_points(self.store, *key)
        encoder = SpaceEncoder(points.space)
        z = encoder.encode_points(points.x) if points.x else np.zeros((0, encoder.dim))
        y = np.asarray(points.feasible, dtype=bool)
        entry = _Entry(points.space, encoder, z, y, points.last_point_id, _prior(z, y))
        entry.checked_at = time.monotonic()
        with self._cond:
            entry = self._entries.setdefault(key, entry)
        if _needs_model(entry.y):
            self._enqueue(key)
        return entry

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._stopping:
                    self._cond.wait()
                if self._stopping:
                    return
                key, _ = self._queue.popitem(last=False)
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
            entry = self._load_new(key)
        else:
            with entry.merging:
                new = load_training_points(self.store, *key, after_point_id=entry.last_point_id)
                entry = self._merge(key, entry, new)
        if entry.n_fitted == entry.n_points:
            return  # nothing new (after an error: retried when points arrive)
        if not _needs_model(entry.y):
            with self._cond:
                entry.predictor = _prior(entry.z, entry.y)
                entry.n_fitted, entry.status = entry.n_points, "prior"
            return
        z, y, warm, n = entry.z, entry.y, entry.fit, entry.n_points
        fit = self._fit(z, y, warm)
        self.fits += 1
        _record_fit(fit.fit_seconds, n)
        seen = _seen_choices(entry.encoder, z[:n])
        with self._cond:
            entry.fit, entry.predictor, entry.seen = fit, fit.predictor, seen
            entry.n_fitted, entry.status, entry.error = n, "ready", None
            entry.fitted_at = datetime.now(UTC)

    def _fit(self, z: np.ndarray, y: np.ndarray, warm: Fit | None) -> Fit:
        with self._cond:
            if self._stopping:
                raise RuntimeError("the surrogate engine is stopping")
            if self._executor is None:
                self._executor = self._new_executor()
        args = (z, y, 0, warm, self.config.max_inducing)
        try:
            future = self._executor.submit(fitproc.fit_job, *args)
        except (RuntimeError, OSError) as exc:
            if not isinstance(self._executor, ProcessPoolExecutor):
                raise
            # e.g. spawn refused inside an unguarded `__main__` script: fit in a thread instead.
            log.warning("cannot start the fit process (%s); fitting in a thread", exc)
            self._executor.shutdown(wait=False, cancel_futures=True)
            self._executor = self._new_executor(in_process=False)
            future = self._executor.submit(fitproc.fit_job, *args)
        try:
            return future.result()
        except BrokenProcessPool:
            if self._stopping:
                raise
            log.warning("fit worker died; starting a new one")
            self._executor = self._new_executor()
            return self._executor.submit(fitproc.fit_job, *args).result()

    def _merge(self, key: Key, entry: _Entry, new: TrainingPoints) -> _Entry:
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


def _record_fit(seconds: float, n_points: int, ok: bool = True) -> None:
    try:
        from server.observability import record_fit
    except ImportError:
        return
    record_fit(seconds, n_points, ok)

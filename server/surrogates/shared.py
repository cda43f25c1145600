"""Fits shared through the database, so that replicas of one service fit each version once.

A type's latest fit is a row of `cp_fits` (its predictor as a `surrogate.snapshot`, its warm
start as `torch.save` bytes); `n_fitted`, the version, only grows. A replica about to fit a
type first loads a stored fit that already covers its points; else it claims the type with a
PostgreSQL advisory lock (`pg_try_advisory_lock`, held on a connection of its own for the
length of the fit, so a replica that dies mid-fit lets go with its connection), looks again
under the lock, and only then fits and saves. A replica that finds the type claimed fits
nothing and looks again later. SQLite serves one process: there the claim always succeeds,
and the stored fit lets a restarted service answer with its last model at once.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import torch
from sqlalchemy import select, text
from sqlalchemy.dialects import postgresql, sqlite

from server.db import Store
from server.errors import ServiceError
from server.orm import FitRow, TypeRow, utcnow
from surrogate import snapshot
from surrogate.models import Fit

log = logging.getLogger("cpkb.surrogates")

# The advisory-lock class of fit claims (two-key form: class, type row id); "cpkf".
FIT_LOCK_CLASS = 0x63706B66
_FITS = FitRow.__table__


@dataclass(frozen=True)
class StoredFit:
    fit: Fit
    fitted_by: str
    fitted_at: datetime


def _warm_bytes(state: dict[str, Any] | None) -> bytes | None:
    if state is None:
        return None
    buffer = io.BytesIO()
    torch.save(state, buffer)
    return buffer.getvalue()


def _warm_state(data: bytes | None) -> dict[str, Any] | None:
    """The warm start saved with a fit; None (a cold start) if this version cannot read it."""
    if data is None:
        return None
    try:
        return torch.load(io.BytesIO(data), weights_only=True)
    except Exception as exc:  # any unreadable state only costs the next fit its warm start
        log.warning("stored warm start unreadable (%s); the next fit starts cold", exc)
        return None


class FitShare:
    """The stored fits of one service's database, and the claims on fitting them."""

    def __init__(self, store: Store, replica: str) -> None:
        self.store = store
        self.replica = replica

    def version(self, type_pk: int) -> int:
        """The stored fit's version (0: none), one indexed read."""
        with self.store.transaction() as session:
            found = session.scalar(select(FitRow.n_fitted).where(FitRow.type_pk == type_pk))
        return found or 0

    def newer(self, type_pk: int, than: int) -> StoredFit | None:
        """The stored fit, if its version is above `than` (the cheap version read first)."""
        if self.version(type_pk) <= than:
            return None
        with self.store.transaction() as session:
            row = session.get(FitRow, type_pk)
            if row is None or row.n_fitted <= than:
                return None
            try:
                predictor = snapshot.load(row.predictor)
            except snapshot.SnapshotError as exc:
                log.warning("stored fit of type row %s unreadable (%s); fitting anew", type_pk, exc)
                return None
            fit = Fit(
                row.kind,
                predictor,
                row.n_fitted,
                row.fit_seconds,
                row.iterations,
                row.train_accuracy,
                row.lengthscales,
                _warm_state(row.warm_state),
            )
            return StoredFit(fit, row.fitted_by, row.fitted_at)

    @contextmanager
    def claim(self, type_pk: int) -> Iterator[bool]:
        """True while this replica holds the right to fit the type; False if another does."""
        if self.store.dialect != "postgresql":
            yield True
            return
        with self.store.engine.connect() as conn:
            args = {"cls": FIT_LOCK_CLASS, "key": type_pk}
            got = bool(conn.scalar(text("SELECT pg_try_advisory_lock(:cls, :key)"), args))
            conn.commit()  # the lock is the session's: no transaction stays open during a fit
            try:
                yield got
            finally:
                if got:
                    try:
                        conn.execute(text("SELECT pg_advisory_unlock(:cls, :key)"), args)
                        conn.commit()
                    except Exception:
                        conn.invalidate()  # closing the connection ends the lock with it
                        raise

    def save(self, type_pk: int, fit: Fit, created_at: datetime | None = None) -> bool:
        """Store `fit` unless the stored one is as new; False if not stored (superseded, or the
        type is gone). `created_at`: the type row the fit was made for; a row id freed by a
        deleted knowledge base is taken again by the next type (SQLite reuses it), and a fit
        that finishes after its type was deleted must not become the new type's."""
        try:
            predictor = snapshot.dump(fit.predictor)
        except TypeError as exc:  # a predictor kind snapshots do not carry: kept here only
            log.warning("fit of type row %s not stored: %s", type_pk, exc)
            return False
        values = {
            "type_pk": type_pk,
            "n_fitted": fit.n_fitted,
            "kind": fit.kind,
            "predictor": predictor,
            "warm_state": _warm_bytes(fit.warm_state),
            "fit_seconds": fit.fit_seconds,
            "iterations": fit.iterations,
            "train_accuracy": fit.train_accuracy,
            "lengthscales": fit.lengthscales,
            "fitted_by": self.replica,
            "fitted_at": utcnow(),
        }
        module = postgresql if self.store.dialect == "postgresql" else sqlite
        stmt = module.insert(_FITS).values(values)
        stmt = stmt.on_conflict_do_update(
            index_elements=["type_pk"],
            set_={k: stmt.excluded[k] for k in values if k != "type_pk"},
            where=_FITS.c.n_fitted < stmt.excluded.n_fitted,
        ).returning(_FITS.c.type_pk)
        try:
            with self.store.transaction(write=True) as session:
                if created_at is not None:
                    row_created = session.scalar(
                        select(TypeRow.created_at).where(TypeRow.id == type_pk)
                    )
                    if row_created != created_at:
                        log.info("fit of type row %s not stored: the type is gone", type_pk)
                        return False
                return session.execute(stmt).first() is not None
        except ServiceError as exc:  # the type was deleted meanwhile (a foreign-key refusal)
            log.info("fit of type row %s not stored: %s", type_pk, exc)
            return False

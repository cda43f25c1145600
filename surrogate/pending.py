"""Suggestions served but not yet answered by a point (the pending trials of Ax / Optuna).

The optimiser pushes new suggestions away from these, so that planners asking at the same moment
for the same space do not all get one point. An entry leaves the book when a point arrives for one
of its constraint types at its values, or when it expires (`ttl_s`).

`Pending` is the interface the suggestion core and the service's engine use; `PendingBook`
keeps the entries in this process, and the service's replicas on one PostgreSQL share theirs
through the database (`server.surrogates.pending_db.DatabasePendingBook`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeGuard

import numpy as np

from surrogate.encoding import Value

MAX_PER_KB = 1000


@dataclass(frozen=True)
class PendingEntry:
    x: dict[str, Value]  # the search variables of the suggestion (free and fixed)
    binds: tuple[tuple[str, tuple[tuple[str, str], ...]], ...]  # (type_id, ((label, var), ...))
    expires: float

    @property
    def type_ids(self) -> frozenset[str]:
        return frozenset(type_id for type_id, _ in self.binds)


Binds = Sequence[tuple[str, Mapping[str, str]]]


def _entry(x: Mapping[str, Value], binds: Binds, expires: float) -> PendingEntry:
    return PendingEntry(dict(x), tuple((t, tuple(sorted(b.items()))) for t, b in binds), expires)


class Pending(Protocol):
    """A book of pending suggestions, keyed by knowledge base (see the module's docstring)."""

    ttl_s: float

    def add(self, kb: str, x: Mapping[str, Value], binds: Binds) -> None: ...

    def for_request(self, kb: str, type_ids: frozenset[str]) -> list[dict[str, Value]]: ...

    def answered(self, kb: str, type_id: str, points: Sequence[Mapping[str, Value]]) -> int: ...

    def count(self, kb: str) -> int: ...


SAME_ATOL = 1e-9
"""How far a point's value may lie from a suggestion's and still answer it (a value round-tripped
through JSON and a database comes back within it)."""


def _same(a: Value, b: object) -> bool:
    """`a` and `b` within `SAME_ATOL` everywhere, as `np.allclose(a, b, rtol=0)` says. Flat
    sequences of numbers, the common case, are compared in Python: a planner calls this for each
    pending entry at each point it posts, where numpy's per-call overhead outweighs the
    comparison."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    if _first_apart(a, b):
        return False  # every branch below compares the first values (the common verdict)
    if _numbers(a) and _numbers(b) and len(a) == len(b):
        return all(x == y or abs(x - y) <= SAME_ATOL for x, y in zip(a, b, strict=True))
    try:
        return bool(np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=0, atol=SAME_ATOL))
    except (TypeError, ValueError):
        return False


def _first_apart(a: object, b: object) -> bool:
    """The first values of two sequences are numbers farther apart than `SAME_ATOL` (a NaN or
    an infinity is left to the full comparison)."""
    if not (isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)) and a and b):
        return False
    x, y = a[0], b[0]
    return isinstance(x, (int, float)) and isinstance(y, (int, float)) and abs(x - y) > SAME_ATOL


def _numbers(value: object) -> TypeGuard[Sequence[float]]:
    return isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value)


class PendingBook:
    """Thread-safe: in the service, request threads add and the fit worker resolves; a planner
    suggesting in its own process keeps one too (`planner.knowledge.local`)."""

    def __init__(self, ttl_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.ttl_s = ttl_s
        self.clock = clock
        self._lock = threading.Lock()
        self._by_kb: dict[str, list[PendingEntry]] = {}

    def add(self, kb: str, x: Mapping[str, Value], binds: Binds) -> None:
        entry = _entry(x, binds, self.clock() + self.ttl_s)
        with self._lock:
            entries = self._live(kb)
            entries.append(entry)
            del entries[:-MAX_PER_KB]

    def for_request(self, kb: str, type_ids: frozenset[str]) -> list[dict[str, Value]]:
        """Pending points of requests sharing a constraint type with this one (or, for a request
        without constraints, those of other unconstrained requests)."""
        with self._lock:
            entries = self._live(kb)
            if type_ids:
                return [e.x for e in entries if e.type_ids & type_ids]
            return [e.x for e in entries if not e.binds]

    def answered(self, kb: str, type_id: str, points: Sequence[Mapping[str, Value]]) -> int:
        """Drop entries that `points` (new points of `type_id`, keyed by decision label) answer;
        returns how many were dropped."""
        if not points:
            return 0
        with self._lock:
            entries = self._live(kb)
            keep = [e for e in entries if not answers(e, type_id, points)]
            dropped = len(entries) - len(keep)
            self._by_kb[kb] = keep
            return dropped

    def count(self, kb: str) -> int:
        with self._lock:
            return len(self._live(kb))

    def _live(self, kb: str) -> list[PendingEntry]:
        now = self.clock()
        entries = [e for e in self._by_kb.get(kb, []) if e.expires > now]
        self._by_kb[kb] = entries
        return entries


def answers(entry: PendingEntry, type_id: str, points: Sequence[Mapping[str, Value]]) -> bool:
    for bound_type, bind in entry.binds:
        if bound_type != type_id:
            continue
        for point in points:
            if all(
                label in point and _same(entry.x[var], point[label])
                for label, var in bind
                if var in entry.x  # a lookahead suggestion gives only the node's variables
            ):
                return True
    return False

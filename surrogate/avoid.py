"""The points a suggestion keeps away from: excluded ones (never returned) and pending ones
(served to some planner, not answered yet: avoided softly).

An excluded (or pending) point may give only some of the free variables: it then excludes (or
repels) every point that agrees with it on those. A planner that looks ahead asks for a node's
variable jointly with the later decisions its constraints involve, and excludes the node's
existing children by the node's variable alone. Distances to such a point are measured on its
variables only, so "far from the existing children" means far in the node's own variable.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from surrogate.domains import CategoricalDomain, Domain, Value
from surrogate.encoding import Columns, EncodingError, SpaceEncoder, encoder_for
from surrogate.kernels import squared_distances


@dataclass(frozen=True)
class _Group:
    """Excluded points that give the same variables: their columns and encoded rows."""

    names: tuple[str, ...]
    cols: Columns
    z: np.ndarray  # (k, d) encoded on the group's own variables
    mask: np.ndarray  # (d,) columns of the full encoding that the group's variables occupy
    walls: np.ndarray  # (d,) bool: which of those columns are continuous (bounded by walls)


def _agrees(point: Mapping[str, Value], fixed: Mapping[str, Value]) -> bool:
    return all(point.get(k, v) == v for k, v in fixed.items())


class AvoidSet:
    """Excluded and pending points of one request, on the free variables of `free`."""

    def __init__(
        self,
        free: Mapping[str, Domain],
        fixed: Mapping[str, Value],
        exclude: Sequence[Mapping[str, Value]],
        pending: Sequence[Mapping[str, Value]],
        *,
        walls: bool = True,
    ) -> None:
        """`walls`: whether `spread` counts the continuous variables' walls as mirrors."""
        self.free = dict(free)
        self.fixed = dict(fixed)
        self.encoder = encoder_for(free, separations=False)
        self.blocks = {v.name: np.arange(v.start, v.start + v.z_width) for v in self.encoder.vars}
        self._walls = {v.name: v.walls() & walls for v in self.encoder.vars}
        self._check_exclude(exclude)
        self.groups = self._groups([p for p in exclude if _agrees(p, fixed)], "exclude")
        self.pending_groups = self._groups(
            [p for p in pending if _agrees(p, fixed)], "pending", drop_invalid=True
        )

    def only(self, exclude: Sequence[Mapping[str, Value]]) -> AvoidSet:
        """A set of just `exclude`, on this set's variables and without its pending points: what
        a batch's next pick adds. A union's `excluded` is its parts' or-ed, its `nearest` their
        minimum, so a batch updates its candidates' verdicts rather than recomputing them."""
        self._check_exclude(exclude)
        part = copy.copy(self)
        part.groups = self._groups([p for p in exclude if _agrees(p, self.fixed)], "exclude")
        part.pending_groups = []
        return part

    def _check_exclude(self, exclude: Sequence[Mapping[str, Value]]) -> None:
        for i, point in enumerate(exclude):
            if not any(name in point for name in self.free):
                raise EncodingError(f"exclude[{i}]", "gives none of the free variables")

    def _sub_encoder(self, names: tuple[str, ...]) -> SpaceEncoder:
        return encoder_for({name: self.free[name] for name in names}, separations=False)

    def _groups(
        self, points: Sequence[Mapping[str, Value]], where: str, *, drop_invalid: bool = False
    ) -> list[_Group]:
        """The points grouped by the free variables they give, each group encoded at once.
        `drop_invalid` (pending points, which come from other requests): a point without a
        free variable or with an invalid value is left out, found point by point only in a
        group that fails; otherwise the first invalid value raises, naming `where`."""
        by_names: dict[tuple[str, ...], list[Mapping[str, Value]]] = {}
        for point in points:
            names = tuple(name for name in self.free if name in point)
            if names:
                by_names.setdefault(names, []).append(point)
        groups = []
        for names, members in by_names.items():
            sub = self._sub_encoder(names)
            try:
                cols = sub.columns(members, where=where)
            except EncodingError:
                if not drop_invalid:
                    raise
                members = [p for p in members if _valid(sub, p)]
                if not members:
                    continue
                cols = sub.columns(members, where=where)
            mask = np.concatenate([self.blocks[name] for name in names])
            walls = np.concatenate([self._walls[name] for name in names])
            groups.append(_Group(names, cols, sub.encode(cols), mask, walls))
        return groups

    @property
    def empty(self) -> bool:
        return not self.groups and not self.pending_groups

    @property
    def has_pending(self) -> bool:
        return bool(self.pending_groups)

    def excluded(self, cols: Columns) -> np.ndarray:
        """`(n,)` whether each candidate agrees with an excluded point (continuous values:
        within 1e-6 of the range)."""
        n = len(next(iter(cols.values())))
        out = np.zeros(n, dtype=bool)
        for group in self.groups:
            same = np.ones((n, len(group.z)), dtype=bool)
            for name in group.names:
                a, b, domain = cols[name], group.cols[name], self.free[name]
                if isinstance(domain, CategoricalDomain):
                    same &= a[:, None] == b[None, :]
                else:
                    tol = 1e-6 * (np.asarray(domain.high) - np.asarray(domain.low))
                    same &= (np.abs(a[:, None, :] - b[None, :, :]) <= tol).all(-1)
            out |= same.any(axis=1)
        return out

    def spread(self, z: np.ndarray) -> np.ndarray:
        """`(n,)` normalised distance from each encoded candidate `(n, D)` to the nearest point
        to avoid (0 with none): `nearest`, with none counted as 0."""
        return spread_of(self.nearest(z))

    def nearest(self, z: np.ndarray) -> np.ndarray:
        """`(n,)` normalised distance from each encoded candidate `(n, D)` to the nearest point
        to avoid, each group measured on its own variables (inf with none). A continuous
        variable's walls count as mirrors: a candidate's distance to its own image beyond the
        nearest wall (twice the distance to it) caps it. Without them the most spread point is
        always in a corner of the box, and a node's children pile up on its faces (in yaw, at
        the two ends of one range) where a space-filling design covers its inside."""
        nearest = np.full(len(z), np.inf)
        for group in (*self.groups, *self.pending_groups):
            own = z[:, group.mask]
            nearest = np.minimum(nearest, _distances(own, group.z).min(axis=1))
            if group.walls.any():
                bounded = own[:, group.walls]
                wall = np.minimum(bounded, 1.0 - bounded).min(axis=1)
                nearest = np.minimum(nearest, 2.0 * np.maximum(wall, 0.0) / np.sqrt(own.shape[1]))
        return nearest

    def pending_distances(self, z: np.ndarray) -> np.ndarray:
        """`(n, k)` normalised distances to the pending points."""
        parts = [_distances(z[:, g.mask], g.z) for g in self.pending_groups]
        return np.hstack(parts) if parts else np.zeros((len(z), 0))


def spread_of(nearest: np.ndarray) -> np.ndarray:
    """`AvoidSet.spread` from `AvoidSet.nearest`: no point to avoid counts as 0."""
    return np.where(np.isfinite(nearest), nearest, 0.0)


def _valid(encoder: SpaceEncoder, point: Mapping[str, Value]) -> bool:
    try:
        encoder.columns([point])
    except EncodingError:
        return False
    return True


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`(n, k)` Euclidean distances divided by sqrt(dim), so that 1 spans the unit cube."""
    return np.sqrt(squared_distances(a, b)) / np.sqrt(max(a.shape[1], 1))

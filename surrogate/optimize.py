"""Maximise an acquisition over a mixed decision space with pymoo's NSGA-II.

Genome: one gene in [0, 1] per continuous dimension, one gene in [0, 1) per categorical variable
(choice = floor(gene * k)); SBX and polynomial mutation act on continuous genes, while categorical
genes are exchanged whole between parents and re-drawn uniformly on mutation, so a choice is always
exact and never treated as ordinal. A finite space (categoricals only, small) is enumerated instead.

The score NSGA-II maximises is the acquisition plus a small exploration bonus (distance to the
nearest excluded or pending point) minus a penalty around pending points, so that
equal-probability regions are explored and concurrent planners are pushed apart. An excluded point
is never returned.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.optimize import minimize
from scipy.stats import qmc

from client.models import CategoricalDomain
from surrogate.acquisition import Acquisition
from surrogate.encoding import Columns, Domain, EncodingError, SpaceEncoder, Value, value_column


class SpaceExhausted(ValueError):
    """Every point of a finite space is excluded."""


@dataclass(frozen=True)
class OptimizerConfig:
    """NSGA-II settings. The authors used pop 100 x 100 generations (`authors()`); the default is
    cut to what `benchmarks/synthetic_cpbo.py` measured to reach the same acquisition values."""

    pop_size: int = 24
    n_gen: int = 20
    sbx_eta: float = 15.0
    sbx_prob: float = 0.9
    pm_eta: float = 20.0
    explore: float = 0.02  # bonus per unit of normalised distance to excluded/pending points
    penalty: float = 0.3  # score removed at a pending point (excluded ones are removed exactly)
    radius: float = 0.1  # penalty reach, in normalised distance
    enumerate_limit: int = 2048
    eliminate_duplicates: bool = True

    @staticmethod
    def authors() -> OptimizerConfig:
        return OptimizerConfig(pop_size=100, n_gen=100)


@dataclass(frozen=True)
class Suggestion:
    x: dict[str, Value]  # every space variable (fixed ones at their fixed value)
    value: float  # the acquisition (without exploration terms) at x


class _Genome:
    """Genes <-> columns of the free variables."""

    def __init__(self, space: Mapping[str, Domain]) -> None:
        self.space = dict(space)
        self.slices: dict[str, slice] = {}
        start = 0
        for name, domain in self.space.items():
            width = 1 if isinstance(domain, CategoricalDomain) else len(domain.low)
            self.slices[name] = slice(start, start + width)
            start += width
        self.n_genes = start
        self.categorical = np.zeros(start, dtype=bool)
        for name, domain in self.space.items():
            if isinstance(domain, CategoricalDomain):
                self.categorical[self.slices[name]] = True

    def columns(self, genes: np.ndarray) -> Columns:
        cols: Columns = {}
        for name, domain in self.space.items():
            g = genes[:, self.slices[name]]
            if isinstance(domain, CategoricalDomain):
                k = len(domain.choices)
                cols[name] = np.minimum((g[:, 0] * k).astype(int), k - 1)
            else:
                low, high = np.asarray(domain.low), np.asarray(domain.high)
                cols[name] = low + np.clip(g, 0.0, 1.0) * (high - low)
        return cols


class _MixedSBX(SBX):
    def __init__(self, categorical: np.ndarray, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.categorical = categorical

    def _do(self, problem, X, *args, random_state=None, **kwargs):  # type: ignore[no-untyped-def]
        q = super()._do(problem, X, *args, random_state=random_state, **kwargs)
        if self.categorical.any():
            cat = self.categorical
            swap = random_state.random((X.shape[1], int(cat.sum()))) < 0.5
            q[0][:, cat] = np.where(swap, X[1][:, cat], X[0][:, cat])
            q[1][:, cat] = np.where(swap, X[0][:, cat], X[1][:, cat])
        return q


class _MixedPM(PM):
    def __init__(self, categorical: np.ndarray, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.categorical = categorical

    def _do(self, problem, X, *args, random_state=None, **kwargs):  # type: ignore[no-untyped-def]
        cat = self.categorical
        out = super()._do(problem, X, *args, random_state=random_state, **kwargs)
        if cat.any():
            out[:, cat] = X[:, cat]
            redraw = random_state.random((len(X), int(cat.sum()))) < 1.0 / problem.n_var
            out[:, cat] = np.where(redraw, random_state.random(redraw.shape), out[:, cat])
        return out


class _Scorer:
    """Acquisition + exploration bonus - penalty near excluded/pending points, on genes."""

    def __init__(
        self,
        acquisition: Acquisition,
        genome: _Genome,
        encoder: SpaceEncoder,
        avoid: np.ndarray,
        n_excluded: int,
        config: OptimizerConfig,
        fixed_cols: Columns,
    ) -> None:
        self.acquisition = acquisition
        self.fixed_cols = fixed_cols  # 1-row columns of fixed space variables
        self.genome = genome
        self.encoder = encoder
        self.avoid = avoid  # (k, D) encoded excluded, then pending points
        self.n_excluded = n_excluded
        self.config = config
        self.norm = np.sqrt(max(encoder.dim, 1))

    def distances(self, z: np.ndarray) -> np.ndarray:
        """`(n, k)` normalised distances to the points to avoid."""
        d2 = ((z[:, None, :] - self.avoid[None, :, :]) ** 2).sum(-1)
        return np.sqrt(d2) / self.norm

    def __call__(self, genes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cols = self.genome.columns(genes)
        raw = np.asarray(self.acquisition({**cols, **self.fixed_cols}), dtype=float)
        raw = np.broadcast_to(raw, (len(genes),))
        if len(self.avoid) == 0:
            return raw, raw
        d = self.distances(self.encoder.encode(cols))
        cfg = self.config
        bonus = cfg.explore * np.minimum(d.min(axis=1), 1.0)
        pending = d[:, self.n_excluded :]
        if pending.shape[1] == 0:
            return raw + bonus, raw
        penalty = cfg.penalty * np.exp(-0.5 * (pending / cfg.radius) ** 2).max(axis=1)
        return raw + bonus - penalty, raw


class _Problem(Problem):
    def __init__(self, scorer: _Scorer) -> None:
        super().__init__(n_var=scorer.genome.n_genes, n_obj=1, xl=0.0, xu=1.0)
        self.scorer = scorer

    def _evaluate(self, x, out, *args, **kwargs):  # type: ignore[no-untyped-def]
        out["F"] = -self.scorer(x)[0]


def _validated(
    space: Mapping[str, Domain], points: Sequence[Mapping[str, Value]], what: str
) -> Columns:
    return SpaceEncoder(space).columns(points, where=what)


def _split(
    space: Mapping[str, Domain], fixed: Mapping[str, Value]
) -> tuple[dict[str, Domain], dict[str, Value]]:
    """The free sub-space, and validated fixed values of space variables."""
    for name, domain in space.items():
        if name in fixed:
            value_column(f"fixed.{name}", domain, [fixed[name]])
    free = {k: d for k, d in space.items() if k not in fixed}
    return free, {k: v for k, v in fixed.items() if k in space}


def _fits(space: Mapping[str, Domain], point: Mapping[str, Value]) -> bool:
    try:
        _validated(space, [point], "pending")
    except EncodingError:
        return False
    return True


def _avoid_rows(
    free: Mapping[str, Domain],
    fixed_in_space: Mapping[str, Value],
    exclude: Sequence[Mapping[str, Value]],
    pending: Sequence[Mapping[str, Value]],
) -> tuple[Columns, Columns]:
    """Columns (free variables) of the excluded and of the pending points that agree with the
    fixed values. Bad excluded values raise; pending points that do not fit are ignored."""

    def agrees(point: Mapping[str, Value]) -> bool:
        return all(point.get(k, v) == v for k, v in fixed_in_space.items())

    excluded = _validated(free, [p for p in exclude if agrees(p)], "exclude")
    fitting = [p for p in pending if agrees(p) and _fits(free, p)]
    return excluded, _validated(free, fitting, "pending")


def _is_excluded(cand: Columns, excluded: Columns, free: Mapping[str, Domain]) -> np.ndarray:
    """`(n,)` whether each candidate equals an excluded point (continuous: within 1e-6 of range)."""
    n = len(next(iter(cand.values())))
    m = len(next(iter(excluded.values()))) if excluded else 0
    if m == 0:
        return np.zeros(n, dtype=bool)
    same = np.ones((n, m), dtype=bool)
    for name, domain in free.items():
        a, b = cand[name], excluded[name]
        if isinstance(domain, CategoricalDomain):
            same &= a[:, None] == b[None, :]
        else:
            tol = 1e-6 * (np.asarray(domain.high) - np.asarray(domain.low))
            same &= (np.abs(a[:, None, :] - b[None, :, :]) <= tol).all(-1)
    return same.any(axis=1)


def maximize(
    acquisition: Acquisition,
    space: Mapping[str, Domain],
    *,
    fixed: Mapping[str, Value] | None = None,
    exclude: Sequence[Mapping[str, Value]] = (),
    pending: Sequence[Mapping[str, Value]] = (),
    seed: int = 0,
    config: OptimizerConfig | None = None,
) -> Suggestion:
    """The point of `space` (minus `fixed` variables) that maximises `acquisition`, never one in
    `exclude`; `pending` points (served, not yet answered) are avoided softly. Deterministic for a
    given seed. Raises EncodingError (naming the field) on bad values, SpaceExhausted when a finite
    space is wholly excluded."""
    config = config or OptimizerConfig()
    fixed = fixed or {}
    free, fixed_in_space = _split(space, fixed)
    if not free:
        fixed_cols = {k: value_column(k, space[k], [v]) for k, v in fixed_in_space.items()}
        return Suggestion(dict(fixed_in_space), float(np.asarray(acquisition(fixed_cols))[0]))
    genome = _Genome(free)
    encoder = SpaceEncoder(free)
    excluded, pending_cols = _avoid_rows(free, fixed_in_space, exclude, pending)
    avoid = np.vstack([encoder.encode(excluded), encoder.encode(pending_cols)])
    fixed_cols = {k: value_column(k, space[k], [v]) for k, v in fixed_in_space.items()}
    n_excluded = len(next(iter(excluded.values())))
    scorer = _Scorer(acquisition, genome, encoder, avoid, n_excluded, config, fixed_cols)

    genes = _candidates(genome, free, scorer, config, seed)
    ok = ~_is_excluded(genome.columns(genes), excluded, free)
    if not ok.any():
        if _finite_size(free) is not None:
            raise SpaceExhausted("every point of the space is excluded")
        genes = np.random.default_rng(seed).random((config.pop_size, genome.n_genes))
        ok = ~_is_excluded(genome.columns(genes), excluded, free)
    score, raw = scorer(genes)
    best = int(np.argmax(np.where(ok, score, -np.inf)))
    x = encoder.points(genome.columns(genes[best : best + 1]))[0]
    merged = {**x, **fixed_in_space}
    return Suggestion({k: merged[k] for k in space}, float(raw[best]))


def _finite_size(free: Mapping[str, Domain]) -> int | None:
    if not all(isinstance(d, CategoricalDomain) for d in free.values()):
        return None
    return int(np.prod([len(d.choices) for d in free.values()]))  # type: ignore[union-attr]


def _candidates(
    genome: _Genome,
    free: Mapping[str, Domain],
    scorer: _Scorer,
    config: OptimizerConfig,
    seed: int,
) -> np.ndarray:
    """All points of a small finite space, else NSGA-II's final population plus its start."""
    size = _finite_size(free)
    if size is not None and size <= config.enumerate_limit:
        ks = [len(d.choices) for d in free.values()]  # type: ignore[union-attr]
        grid = np.array(list(itertools.product(*[range(k) for k in ks])), dtype=float)
        return (grid + 0.5) / np.asarray(ks, dtype=float)
    return _nsga2(genome, scorer, config, seed)


def space_filling_genes(n_genes: int, n: int, seed: int) -> np.ndarray:
    """Latin hypercube genes `(n, n_genes)`: stratified in every continuous dimension and
    balanced over the choices of every categorical."""
    return qmc.LatinHypercube(d=n_genes, seed=seed).random(n)


def _nsga2(genome: _Genome, scorer: _Scorer, config: OptimizerConfig, seed: int) -> np.ndarray:
    start = space_filling_genes(genome.n_genes, config.pop_size, seed)
    algorithm = NSGA2(
        pop_size=config.pop_size,
        sampling=start,
        crossover=_MixedSBX(genome.categorical, eta=config.sbx_eta, prob=config.sbx_prob),
        mutation=_MixedPM(genome.categorical, eta=config.pm_eta),
        eliminate_duplicates=config.eliminate_duplicates,
    )
    problem = _Problem(scorer)
    result = minimize(problem, algorithm, ("n_gen", config.n_gen), seed=seed, verbose=False)
    return np.vstack([result.pop.get("X"), start])


def space_filling(
    space: Mapping[str, Domain],
    *,
    fixed: Mapping[str, Value] | None = None,
    exclude: Sequence[Mapping[str, Value]] = (),
    pending: Sequence[Mapping[str, Value]] = (),
    seed: int = 0,
) -> dict[str, Value]:
    """The Voronoi sampler of the paper's quasi-random baseline: of 10 x dim uniform candidates,
    the one farthest from the excluded and pending points (never an excluded one)."""
    fixed = fixed or {}
    free, fixed_in_space = _split(space, fixed)
    if not free:
        return dict(fixed_in_space)
    genome = _Genome(free)
    encoder = SpaceEncoder(free)
    excluded, pending_cols = _avoid_rows(free, fixed_in_space, exclude, pending)
    avoid = np.vstack([encoder.encode(excluded), encoder.encode(pending_cols)])
    size = _finite_size(free)
    if size is not None and size <= OptimizerConfig().enumerate_limit:
        ks = [len(d.choices) for d in free.values()]  # type: ignore[union-attr]
        grid = np.array(list(itertools.product(*[range(k) for k in ks])), dtype=float)
        genes = np.random.default_rng(seed).permutation((grid + 0.5) / np.asarray(ks, float))
    else:
        genes = np.random.default_rng(seed).random((10 * max(encoder.dim, 1), genome.n_genes))
    cols = genome.columns(genes)
    ok = ~_is_excluded(cols, excluded, free)
    if not ok.any():
        raise SpaceExhausted("every point of the space is excluded")
    if len(avoid):
        z = encoder.encode(cols)
        spread = np.sqrt(((z[:, None, :] - avoid[None, :, :]) ** 2).sum(-1)).min(axis=1)
    else:
        spread = np.zeros(len(genes))
    best = int(np.argmax(np.where(ok, spread, -np.inf)))
    merged = {**encoder.points(genome.columns(genes[best : best + 1]))[0], **fixed_in_space}
    return {k: merged[k] for k in space}

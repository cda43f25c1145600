"""Maximise an acquisition over a mixed decision space with pymoo's NSGA-II.

Genome: one gene in [0, 1] per continuous dimension, one gene in [0, 1) per categorical variable
(choice = floor(gene * k)); SBX and polynomial mutation act on continuous genes, while categorical
genes are exchanged whole between parents and re-drawn uniformly on mutation, so a choice is always
exact and never treated as ordinal. A finite space (categoricals only, small) is enumerated instead.

Like BoTorch's `optimize_acqf`, the search starts from raw samples (a Latin hypercube, scored in
one vectorised call) and NSGA-II refines the best of them for a few generations (pymoo's SBX and
polynomial mutation, driven on arrays; see `_nsga2`), each point scored once. The score NSGA-II
maximises is the acquisition plus a small exploration bonus (distance to the nearest excluded or
pending point) minus the acquisition's penalty around its pending points
(`surrogate.acquisition.PendingPoints`), so that concurrent planners are pushed apart. An excluded
point is never returned.

With `mpf_margin > 0` the answer is not the argmax itself but the candidate farthest from the
excluded and pending points among those within that fraction of the best acquisition value: for
MPF, "about as likely feasible as the best, as far from the node's other children as possible".
A tree search needs its children spread (the quasi-random baseline's Voronoi rule) as well as
feasible: children piled on one maximum fail together on every constraint the knowledge base
does not know yet.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymoo.core.population import Population
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from scipy.stats import qmc

from surrogate.acquisition import Acquisition
from surrogate.avoid import AvoidSet, spread_of
from surrogate.config import OptimizerConfig
from surrogate.domains import CategoricalDomain, Domain, Value
from surrogate.encoding import Columns, value_column


class SpaceExhausted(ValueError):
    """Every point of a finite space is excluded."""


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

    def genes(self, partial: Mapping[str, Value], base: np.ndarray) -> np.ndarray:
        """`base` (one row of genes) with the variables `partial` gives set to its values
        (those outside the free space, or not of their domain, are ignored)."""
        genes = np.array(base, dtype=float)
        for name, value in partial.items():
            domain = self.space.get(name)
            if domain is None:
                continue
            where = self.slices[name]
            if isinstance(domain, CategoricalDomain):
                if value in domain.choices:
                    genes[where] = (domain.choices.index(value) + 0.5) / len(domain.choices)
                continue
            low, high = np.asarray(domain.low), np.asarray(domain.high)
            point = np.asarray(value, dtype=float).reshape(-1)
            if point.shape == low.shape:  # a domain's bounds are strictly ordered
                genes[where] = np.clip((point - low) / (high - low), 0.0, 1.0)
        return genes


class _MixedSBX(SBX):
    def __init__(self, categorical: np.ndarray, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.categorical = categorical

    def _do(
        self,
        problem: Problem,
        X: np.ndarray,
        *args: Any,
        random_state: np.random.Generator,
        **kwargs: Any,
    ) -> np.ndarray:
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

    def _do(
        self,
        problem: Problem,
        X: np.ndarray,
        *args: Any,
        random_state: np.random.Generator,
        **kwargs: Any,
    ) -> np.ndarray:
        cat = self.categorical
        out = super()._do(problem, X, *args, random_state=random_state, **kwargs)
        if cat.any():
            out[:, cat] = X[:, cat]
            redraw = random_state.random((len(X), int(cat.sum()))) < 1.0 / problem.n_var
            out[:, cat] = np.where(redraw, random_state.random(redraw.shape), out[:, cat])
        return out


class _Scorer:
    """Acquisition + exploration bonus - the acquisition's penalty near its pending points, on
    genes."""

    def __init__(
        self,
        acquisition: Acquisition,
        genome: _Genome,
        avoid: AvoidSet,
        config: OptimizerConfig,
        fixed_cols: Columns,
    ) -> None:
        self.acquisition = acquisition
        self.fixed_cols = fixed_cols  # 1-row columns of fixed space variables
        self.genome = genome
        self.avoid = avoid
        self.config = config
        self._known: dict[bytes, float] = {}  # columns row -> acquisition, for this request

    def raw(self, genes: np.ndarray) -> np.ndarray:
        """`(n,)` the acquisition at each row of `genes`. Points scored before are not scored
        again: NSGA-II's start population and survivors are rows of earlier evaluations, and
        one GP evaluation per term costs more than the whole of the rest. A point is its
        columns, so genes that differ only inside one categorical choice are one point."""
        cols = self.genome.columns(genes)
        flat = np.column_stack(
            [np.asarray(c, dtype=float).reshape(len(genes), -1) for c in cols.values()]
        )
        keys = [row.tobytes() for row in flat]
        todo: dict[bytes, int] = {}  # each new point once, at its first row
        for i, key in enumerate(keys):
            if key not in self._known:
                todo.setdefault(key, i)
        if todo:
            rows = list(todo.values())
            picked = {name: col[rows] for name, col in cols.items()}
            fresh = np.asarray(self.acquisition({**picked, **self.fixed_cols}), dtype=float)
            for key, value in zip(todo, np.broadcast_to(fresh, (len(rows),)), strict=True):
                self._known[key] = float(value)
        return np.fromiter((self._known[key] for key in keys), dtype=float, count=len(keys))

    def penalty(self, z: np.ndarray) -> np.ndarray:
        """`(n,)` the acquisition's penalty near its pending points at encoded candidates `z`
        (0 with none)."""
        if not self.avoid.has_pending:
            return np.zeros(len(z))
        return self.acquisition.pending.penalty_at(self.avoid.pending_distances(z))

    def score(self, raw: np.ndarray, spread: np.ndarray, penalty: np.ndarray) -> np.ndarray:
        """`(n,)` the score of candidates of acquisition `raw`, `spread` and pending `penalty`."""
        return raw + self.config.explore * np.minimum(spread, 1.0) - penalty

    def __call__(self, genes: np.ndarray) -> np.ndarray:
        """`(n,)` the score NSGA-II maximises."""
        raw = self.raw(genes)
        if self.avoid.empty:
            return raw
        z = self.avoid.encoder.encode(self.genome.columns(genes))
        return self.score(raw, self.avoid.spread(z), self.penalty(z))


def _split(
    space: Mapping[str, Domain], fixed: Mapping[str, Value]
) -> tuple[dict[str, Domain], dict[str, Value]]:
    """The free sub-space, and validated fixed values of space variables."""
    for name, domain in space.items():
        if name in fixed:
            value_column(f"fixed.{name}", domain, [fixed[name]])
    free = {k: d for k, d in space.items() if k not in fixed}
    return free, {k: v for k, v in fixed.items() if k in space}


def maximize(
    acquisition: Acquisition,
    space: Mapping[str, Domain],
    *,
    fixed: Mapping[str, Value] | None = None,
    exclude: Sequence[Mapping[str, Value]] = (),
    seed: int = 0,
    config: OptimizerConfig | None = None,
) -> Suggestion:
    """The point of `space` (minus `fixed` variables) that maximises `acquisition`, never one in
    `exclude`; the acquisition's pending points are avoided softly. Deterministic for a given
    seed. Raises EncodingError (naming the field) on bad values, SpaceExhausted when a finite
    space is wholly excluded."""
    found = maximize_batch(
        acquisition, space, fixed=fixed, exclude=exclude, seed=seed, config=config
    )
    return found[0]


def maximize_batch(
    acquisition: Acquisition,
    space: Mapping[str, Domain],
    *,
    fixed: Mapping[str, Value] | None = None,
    exclude: Sequence[Mapping[str, Value]] = (),
    seed: int = 0,
    config: OptimizerConfig | None = None,
    n: int = 1,
    distinct: Sequence[str] | None = None,
    hints: Sequence[Mapping[str, Value]] = (),
    preferred: int = 0,
) -> list[Suggestion]:
    """Up to `n` points, the first as `maximize` answers; each next one is chosen from the same
    candidates as if the ones before were excluded (on the variables `distinct`, default all free
    ones), so a batch is spread like successive suggestions at one node, for one optimisation.
    Fewer than `n` only when a finite space runs out. `hints`: points (of some free variables)
    where constraints are known to have held, such as bindings other planners passed: scored
    too (a narrow feasible region around one known point is easily missed by the raw samples).
    The batch's first point is the best of the first `preferred` hints (those known to satisfy
    every constraint weighed) when it is as good as the best candidate by the margin rule,
    rather than the most spread of those."""
    config = config or OptimizerConfig()
    fixed = fixed or {}
    free, fixed_in_space = _split(space, fixed)
    fixed_cols = {k: value_column(k, space[k], [v]) for k, v in fixed_in_space.items()}
    if not free:
        value = float(np.asarray(acquisition(fixed_cols))[0])
        return [Suggestion(dict(fixed_in_space), value)]
    genome = _Genome(free)
    avoid = AvoidSet(
        free, fixed_in_space, exclude, acquisition.pending.points, walls=config.spread_walls
    )
    scorer = _Scorer(acquisition, genome, avoid, config, fixed_cols)

    genes, n_hinted = _candidates(genome, free, scorer, config, seed, hints)
    rows = np.arange(len(genes)) - (len(genes) - n_hinted)  # `_candidates` ends with the hints
    hinted = (rows >= 0) & (rows < preferred)
    ok = ~avoid.excluded(genome.columns(genes))
    if not ok.any():
        if _finite_size(free) is not None:
            raise SpaceExhausted("every point of the space is excluded")
        genes = np.random.default_rng(seed).random((config.pop_size, genome.n_genes))
        hinted = np.zeros(len(genes), dtype=bool)
    cols = genome.columns(genes)
    raw = scorer.raw(genes)
    z = avoid.encoder.encode(cols)
    nearest, penalty = avoid.nearest(z), scorer.penalty(z)
    ok = ~avoid.excluded(cols)
    keys = [name for name in free if distinct is None or name in distinct] or list(free)
    found: list[Suggestion] = []
    while len(found) < n:
        if found:  # the pick joins the excluded points: only its own verdicts are new
            picked = avoid.only([{k: found[-1].x[k] for k in keys}])
            ok &= ~picked.excluded(cols)
            nearest = np.minimum(nearest, picked.nearest(z))
        if not ok.any():
            break
        spread = spread_of(nearest)
        score = scorer.score(raw, spread, penalty)
        prefer = hinted if not found else None
        best = _select(ok, score, raw, spread, config.mpf_margin, config.mpf_margin_abs, prefer)
        x = {**avoid.encoder.points(genome.columns(genes[best : best + 1]))[0], **fixed_in_space}
        found.append(Suggestion({k: x[k] for k in space}, float(raw[best])))
    return found


def _select(
    ok: np.ndarray,
    score: np.ndarray,
    raw: np.ndarray,
    spread: np.ndarray,
    margin: float,
    margin_abs: float = 0.0,
    prefer: np.ndarray | None = None,
) -> int:
    """The index of the answer among the allowed (`ok`) candidates: the best score, or with a
    margin the most spread of those within `max(margin * |best|, margin_abs)` of the best
    acquisition (ties: the best score). The absolute part matters where the model rates
    everything as almost surely infeasible: the argmax of such a surface is only its tail
    nearest some feasible point (often one of another grasp or task), and the children piled
    there fail together; among near-equal values, spreading is the better bet. A `prefer`red
    candidate among the near ones wins, the best scored: it is known to be feasible."""
    if margin <= 0 and margin_abs <= 0:
        return int(np.argmax(np.where(ok, score, -np.inf)))
    best = raw[ok].max()
    near = ok & (raw >= best - max(margin * abs(best), margin_abs))
    if prefer is not None and (near & prefer).any():
        return int(np.argmax(np.where(near & prefer, score, -np.inf)))
    order = np.lexsort((-score, -np.round(spread, 9), ~near))
    return int(order[0])


def _finite_size(free: Mapping[str, Domain]) -> int | None:
    sizes = [len(d.choices) for d in free.values() if isinstance(d, CategoricalDomain)]
    return math.prod(sizes) if len(sizes) == len(free) else None


def _candidates(
    genome: _Genome,
    free: Mapping[str, Domain],
    scorer: _Scorer,
    config: OptimizerConfig,
    seed: int,
    hints: Sequence[Mapping[str, Value]] = (),
) -> tuple[np.ndarray, int]:
    """All points of a small finite space, else NSGA-II's final population plus its start and
    then the hints, each completed from the best raw sample (they may start NSGA-II too, so
    that it can refine around them); with how many rows at the end are hints."""
    size = _finite_size(free)
    if size is not None and size <= config.enumerate_limit:
        return _grid_genes(free, seed), 0
    raw = space_filling_genes(genome.n_genes, max(config.raw_samples, config.pop_size), seed)
    hinted = np.zeros((0, genome.n_genes))
    if hints:
        best = raw[int(np.argmax(scorer(raw)))]
        hinted = np.vstack([genome.genes(hint, best)[None, :] for hint in hints])
    if config.generations <= 0:
        return np.vstack([raw, hinted]), len(hinted)
    pool = np.vstack([raw, hinted])
    start = pool[np.argsort(-scorer(pool), kind="stable")[: config.pop_size]]
    return np.vstack([_nsga2(genome, scorer, config, seed, start), raw, hinted]), len(hinted)


def _grid_genes(free: Mapping[str, Domain], seed: int) -> np.ndarray:
    """Every point of a finite (categorical) space as genes, in a seeded order, so that ties
    do not always go to the first choice."""
    ks = [len(d.choices) for d in free.values()]  # type: ignore[union-attr]
    grid = np.array(list(itertools.product(*[range(k) for k in ks])), dtype=float)
    return np.random.default_rng(seed).permutation((grid + 0.5) / np.asarray(ks, float))


def space_filling_genes(n_genes: int, n: int, seed: int) -> np.ndarray:
    """Latin hypercube genes `(n, n_genes)`: stratified in every continuous dimension and
    balanced over the choices of every categorical."""
    return qmc.LatinHypercube(d=n_genes, seed=seed).random(n)


def _nsga2(
    genome: _Genome, scorer: _Scorer, config: OptimizerConfig, seed: int, start: np.ndarray
) -> np.ndarray:
    """Every genome NSGA-II evaluates `(n, n_genes)` in `config.generations - 1` generations from
    `start` `(pop_size, n_genes)`.

    With one objective, NSGA-II's rank-and-crowding comparison is a comparison of scores, so the
    generations are driven here on arrays: binary tournaments on the score, pymoo's SBX and
    polynomial mutation (through their `do`, crossover probability included), and survival of
    the best `pop_size` of parents and offspring. pymoo's `minimize` loop gave the same search
    at several times the cost (its per-individual bookkeeping took most of a suggestion)."""
    rng = np.random.default_rng(seed)
    problem = Problem(n_var=genome.n_genes, n_obj=1, xl=0.0, xu=1.0)  # the operators' bounds
    crossover = _MixedSBX(genome.categorical, eta=config.sbx_eta, prob=config.sbx_prob)
    mutation = _MixedPM(genome.categorical, eta=config.pm_eta)
    pop, score = start, scorer(start)
    evaluated = [start]
    n_matings = -(-config.pop_size // crossover.n_offsprings)
    for _ in range(config.generations - 1):
        parents = _binary_tournaments(score, n_matings * crossover.n_parents, rng)
        offspring = crossover.do(
            problem,
            Population.new("X", pop),
            parents.reshape(n_matings, crossover.n_parents),
            random_state=rng,
        )
        genes = mutation.do(problem, offspring, random_state=rng).get("X")
        genes = np.clip(genes[: config.pop_size], 0.0, 1.0)
        if config.eliminate_duplicates:
            genes = _new_rows(genes, pop)
        if not len(genes):
            break
        evaluated.append(genes)
        both = np.vstack([pop, genes])
        both_score = np.concatenate([score, scorer(genes)])
        keep = np.argsort(-both_score, kind="stable")[: config.pop_size]
        pop, score = both[keep], both_score[keep]
    return np.vstack(evaluated)


def _binary_tournaments(score: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """`(n,)` indices of tournament winners: pairs drawn without replacement (permutations of
    the population, as pymoo's tournament selection does), the higher score wins, ties at random."""
    need = 2 * n
    draws = np.concatenate([rng.permutation(len(score)) for _ in range(-(-need // len(score)))])
    a, b = draws[:need:2], draws[1:need:2]
    coin = rng.random(n) < 0.5
    a_wins = (score[a] > score[b]) | ((score[a] == score[b]) & coin)
    return np.where(a_wins, a, b)


def _new_rows(genes: np.ndarray, pop: np.ndarray) -> np.ndarray:
    """The rows of `genes` that are not rows of `pop` nor repeated (pymoo's duplicate rule)."""
    seen = {row.tobytes() for row in pop}
    keep = []
    for i, row in enumerate(genes):
        key = row.tobytes()
        if key not in seen:
            seen.add(key)
            keep.append(i)
    return genes[keep]


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
    avoid = AvoidSet(free, fixed_in_space, exclude, pending)
    size = _finite_size(free)
    if size is not None and size <= OptimizerConfig().enumerate_limit:
        genes = _grid_genes(free, seed)
    else:
        dim = avoid.encoder.dim
        genes = np.random.default_rng(seed).random((10 * max(dim, 1), genome.n_genes))
    cols = genome.columns(genes)
    ok = ~avoid.excluded(cols)
    if not ok.any():
        raise SpaceExhausted("every point of the space is excluded")
    spread = avoid.spread(avoid.encoder.encode(cols))
    best = int(np.argmax(np.where(ok, spread, -np.inf)))
    merged = {**avoid.encoder.points(genome.columns(genes[best : best + 1]))[0], **fixed_in_space}
    return {k: merged[k] for k in space}

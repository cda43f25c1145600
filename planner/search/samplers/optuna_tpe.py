"""A peer a user might pick instead of CP-BO: Optuna's TPE as the node-expansion sampler.

One Optuna study per decision variable, for the whole run, driven by ask and tell: each
proposal is an asked trial; the trial is told when its child is next seen as a sibling
(the tree revisits that node to widen it), with the child's backed-up reward as the value to
maximise and, as TPE's constraint, whether the child's own transition passed. That verdict
is final at the child's first rollout (failing there gives reward `0.1 (2i+1) / L` at
decision index i; passing gives at least `0.1 (2i+3) / L`), so the constraint is exact.
Children of every node of a variable feed its one study: TPE learns where, say, placements
collide, but does not see the path's earlier decisions (it is no constraint model).
Nothing is kept between runs and the knowledge base is never used.
"""

from __future__ import annotations

import warnings

import optuna
from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution
from optuna.trial import Trial, TrialState

from contract.models import CategoricalDomain, ContinuousDomain, Value
from planner.config import OptunaTpeConfig, PlanConfig
from planner.search.samplers.base import SampleContext
from planner.search.samplers.quasi_random import untried_choice

CONSTRAINT = "transition"


def _distributions(domain: CategoricalDomain | ContinuousDomain) -> dict[str, BaseDistribution]:
    if isinstance(domain, CategoricalDomain):
        return {"choice": CategoricalDistribution(list(domain.choices))}
    return {
        f"x{i}": FloatDistribution(lo, hi)
        for i, (lo, hi) in enumerate(zip(domain.low, domain.high, strict=True))
    }


def _value(domain: CategoricalDomain | ContinuousDomain, params: dict[str, object]) -> Value:
    if isinstance(domain, CategoricalDomain):
        return str(params["choice"])
    return [float(params[f"x{i}"]) for i in range(len(domain.low))]  # type: ignore[arg-type]


def _key(path: dict[str, Value], value: Value) -> str:
    def text(v: Value) -> str:
        return v if isinstance(v, str) else ",".join(f"{f:.12g}" for f in v)

    return "|".join(f"{k}={text(v)}" for k, v in sorted(path.items())) + "->" + text(value)


class OptunaTpeSampler:
    name = "optuna-tpe"
    keeps_knowledge = False

    def __init__(self, *, seed: int, n_layers: int, config: OptunaTpeConfig | None = None) -> None:
        self.config = config if config is not None else OptunaTpeConfig()
        self._seed = seed
        self._n_layers = n_layers
        self._studies: dict[str, optuna.Study] = {}
        self._pending: dict[str, dict[str, Trial]] = {}

    def _study(self, var: str) -> optuna.Study:
        if var not in self._studies:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                sampler = optuna.samplers.TPESampler(
                    seed=self._seed * 1009 + len(self._studies),
                    n_startup_trials=self.config.n_startup_trials,
                    multivariate=True,
                    constant_liar=False,
                )
            self._studies[var] = optuna.create_study(direction="maximize", sampler=sampler)
            self._pending[var] = {}
        return self._studies[var]

    def _tell_siblings(self, ctx: SampleContext, study: optuna.Study) -> None:
        pending = self._pending[ctx.var.var]
        threshold = 0.1 * (2 * ctx.depth + 2) / self._n_layers
        for value, reward in zip(ctx.siblings, ctx.sibling_rewards, strict=True):
            trial = pending.pop(_key(ctx.path, value), None)
            if trial is not None:
                # Optuna's convention: a constraint <= 0 is feasible (the transition passed).
                trial.set_constraint(CONSTRAINT, threshold - reward)
                study.tell(trial, reward)

    def propose(self, ctx: SampleContext) -> Value:
        domain = ctx.var.domain
        study = self._study(ctx.var.var)
        self._tell_siblings(ctx, study)
        distributions = _distributions(domain)
        for _ in range(self.config.max_categorical_asks):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                trial = study.ask(distributions)
            value = _value(domain, trial.params)
            if isinstance(domain, CategoricalDomain) and value in ctx.siblings:
                study.tell(trial, state=TrialState.FAIL)  # tried here already: ask again
                continue
            self._pending[ctx.var.var][_key(ctx.path, value)] = trial
            return value
        assert isinstance(domain, CategoricalDomain)
        return untried_choice(domain, list(ctx.siblings), ctx.rng)

    def propose_untried(self, ctx: SampleContext) -> None:
        return None

    def chain(self) -> None:
        return None

    def close(self) -> None:
        self._studies.clear()
        self._pending.clear()


def factory(*, seed: int, world: object, config: PlanConfig, **_: object) -> OptunaTpeSampler:
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    n_layers = len(world.skeleton.layers)  # type: ignore[attr-defined]
    return OptunaTpeSampler(seed=seed, n_layers=n_layers, config=config.optuna_tpe)

"""MCTS-BO: GP-UCB on the graded rewards of a node's children (task-local; nothing is kept).

At a decision node with at least `MctsBoConfig.min_children` children whose targets differ, a GP
regression (Matern 5/2 ARD, constant mean: `surrogate.models.fit_regression`) is fitted from the
children's values to their targets and the UCB `mu + sqrt(beta) sigma` is maximised (NSGA-II,
`surrogate.optimize.maximize`) away from the children. The target is the backed-up reward graded
within the failed check (`SampleContext.sibling_scores`: an IK residual, a penetration depth):
with the plain reward, children failing at one check score alike and the GP chose only 2-14% of
expansions. With no signal yet (fewer children, or all targets equal, where UCB reduces to pure
variance), the node expands like the Voronoi sampler. Each node warm-starts from its previous fit.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from contract.models import CategoricalDomain, Value
from planner.config import MctsBoConfig, PlanConfig, QuasiRandomConfig
from planner.search.samplers.base import SampleContext
from planner.search.samplers.quasi_random import space_filling

if TYPE_CHECKING:
    from surrogate.models import Fit


class MctsBoSampler:
    name = "mcts-bo"
    keeps_knowledge = False

    def __init__(
        self,
        config: MctsBoConfig | None = None,
        fallback: QuasiRandomConfig | None = None,
        **overrides: Any,
    ) -> None:
        """`overrides`: fields of `config` by name (`beta=0.1`), for a quick variant."""
        self.config = replace(config if config is not None else MctsBoConfig(), **overrides)
        self.fallback = fallback if fallback is not None else QuasiRandomConfig()
        self._fits: dict[tuple, Fit] = {}
        self.guided = 0
        self.unguided = 0

    def propose(self, ctx: SampleContext) -> Value:
        from surrogate.acquisition import ucb
        from surrogate.domains import space_from_json
        from surrogate.encoding import encoder_for
        from surrogate.models import fit_regression
        from surrogate.optimize import maximize

        config = self.config
        domain = ctx.var.domain
        targets = ctx.sibling_scores if config.graded else None
        if targets is None:
            targets = ctx.sibling_rewards
        rewards = targets[-config.max_children_fitted :]
        if isinstance(domain, CategoricalDomain):
            left = [c for c in domain.choices if c not in ctx.siblings]
            if len(left) == 1:
                return left[0]
        if len(rewards) < config.min_children or max(rewards) - min(rewards) < 1e-12:
            self.unguided += 1
            return space_filling(ctx, self.fallback.candidates_per_dim)
        var = ctx.var.var
        space = space_from_json({var: domain.model_dump()})
        values = ctx.siblings[-config.max_children_fitted :]
        z = encoder_for(space).encode_points([{var: v} for v in values])
        key = (var, tuple(sorted((k, str(v)) for k, v in ctx.path.items())))
        seed = int(ctx.rng.integers(2**31 - 1))
        fit = fit_regression(
            z,
            np.asarray(rewards, dtype=float),
            seed=seed,
            warm=self._fits.get(key),
            max_iters=config.fit_iterations,
        )
        self._fits[key] = fit
        suggestion = maximize(
            ucb(fit.predictor, space, config.beta),
            space,
            exclude=[{var: v} for v in ctx.siblings],
            seed=seed,
        )
        self.guided += 1
        return suggestion.x[var]

    def propose_untried(self, ctx: SampleContext) -> None:
        return None

    def chain(self) -> None:
        return None

    def close(self) -> None:
        self._fits.clear()


def factory(*, config: PlanConfig, **_: object) -> MctsBoSampler:
    return MctsBoSampler(config.mcts_bo, config.quasi_random)

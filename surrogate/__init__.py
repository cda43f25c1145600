"""CP-BO's machine learning in one place: encoding, GP surrogates, acquisitions, optimiser.

Imports only numpy/scipy/torch/gpytorch/pymoo/imbalanced-learn/sklearn, and speaks its own types
(`surrogate.domains`, `surrogate.suggest`): the service (MPF suggestions) and the planner (its
snapshot cache, task-local GP-UCB) read the wire models into them at their edges.

    encoder = SpaceEncoder(space)                       # {var: Domain} -> [0, 1]^D
    fit = fit_classifier(encoder.encode_points(xs), feasible, seed=0, warm=previous_fit)
    mpf = MPF([ConstraintTerm.build(type_id, fit.predictor, type_space, bind, fixed)],
              pending=PendingPoints(served_not_answered))
    suggestion = maximize(mpf, space, fixed=fixed, exclude=exclude, seed=0)
    answer = suggest(model_source, SuggestRequest(...), pending_book, key=kb, config=config)

    reg = fit_regression(encoder.encode_points(children), rewards, seed=0)
    suggestion = maximize(UCB.build(reg.predictor, space, beta=2.0, fixed=fixed), space, ...)
"""

from importlib import import_module
from typing import Any

_HOMES = {
    "surrogate.acquisition": ("MPF", "UCB", "Acquisition", "ConstraintTerm", "ucb"),
    "surrogate.encoding": ("Columns", "EncodingError", "SpaceEncoder", "same_domain"),
    "surrogate.models": (
        "Fit",
        "PriorPredictor",
        "RegressionPredictor",
        "VGPPredictor",
        "fit_classifier",
        "fit_label_regression",
        "fit_regression",
        "warm_up",
    ),
    "surrogate.config": ("OptimizerConfig", "SurrogateConfig"),
    "surrogate.optimize": (
        "SpaceExhausted",
        "Suggestion",
        "maximize",
        "space_filling",
    ),
}
_HOME = {name: module for module, names in _HOMES.items() for name in names}


def __getattr__(name: str) -> Any:
    """The names above load their module on first use: `surrogate.config`, which the service's
    settings read, must not pull torch into every command."""
    if name not in _HOME:
        raise AttributeError(f"module 'surrogate' has no attribute {name!r}")
    return getattr(import_module(_HOME[name]), name)


__all__ = [
    "MPF",
    "UCB",
    "Acquisition",
    "Columns",
    "ConstraintTerm",
    "EncodingError",
    "Fit",
    "OptimizerConfig",
    "PriorPredictor",
    "RegressionPredictor",
    "SpaceEncoder",
    "SpaceExhausted",
    "Suggestion",
    "SurrogateConfig",
    "VGPPredictor",
    "fit_classifier",
    "fit_label_regression",
    "fit_regression",
    "maximize",
    "same_domain",
    "space_filling",
    "ucb",
    "warm_up",
]

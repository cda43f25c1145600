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

from surrogate.acquisition import MPF, UCB, Acquisition, ConstraintTerm, ucb
from surrogate.encoding import Columns, EncodingError, SpaceEncoder, same_domain
from surrogate.models import (
    Fit,
    PriorPredictor,
    RegressionPredictor,
    VGPPredictor,
    fit_classifier,
    fit_label_regression,
    fit_regression,
    warm_up,
)
from surrogate.optimize import (
    OptimizerConfig,
    SpaceExhausted,
    Suggestion,
    maximize,
    space_filling,
)

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

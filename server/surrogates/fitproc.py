"""What runs in the fit worker (a child process by default, so that gpytorch's Python-heavy
training never holds the server's GIL). Imports only the surrogate library and the lifeline."""

from __future__ import annotations

import numpy as np

from server.lifeline import exit_with_parent
from surrogate.config import SurrogateConfig
from surrogate.models import Fit, fit_classifier, use_threads, warm_up


def init_worker(threads: int, server_pid: int) -> None:
    """Process initialiser: die with the server (`server_pid`, passed in: see
    `server.lifeline`), leave the other core to it, pay the first-fit cost now. The worker
    keeps the normal priority: at a lower one, planners that keep the cores busy starved it,
    and they were guided for hundreds of rollouts by fits that knew none of their failures
    (BENCHMARKS.md, "Measurements behind the defaults")."""
    exit_with_parent(server_pid)
    use_threads(threads)
    warm_up()


def fit_job(
    z: np.ndarray,
    y: np.ndarray,
    seed: int,
    warm: Fit | None,
    max_inducing: int,
    max_points: int = SurrogateConfig().max_fit_points,
    balance: bool = SurrogateConfig().balance_classes,
) -> Fit:
    return fit_classifier(
        z,
        y,
        seed=seed,
        warm=warm,
        max_inducing=max_inducing,
        max_points=max_points,
        balance=balance,
    )

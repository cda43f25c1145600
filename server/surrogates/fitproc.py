"""What runs in the fit worker (a child process by default, so that gpytorch's Python-heavy
training never holds the server's GIL). Imports only the surrogate library."""

from __future__ import annotations

import numpy as np
import torch

from surrogate.models import Fit, fit_classifier, warm_up


def init_worker(threads: int) -> None:
    """Process initialiser: leave the other core to the server, pay the first-fit cost now."""
    torch.set_num_threads(threads)
    warm_up()


def fit_job(z: np.ndarray, y: np.ndarray, seed: int, warm: Fit | None, max_inducing: int) -> Fit:
    return fit_classifier(z, y, seed=seed, warm=warm, max_inducing=max_inducing)

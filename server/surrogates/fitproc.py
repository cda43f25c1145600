"""What runs in the fit worker (a child process by default, so that gpytorch's Python-heavy
training never holds the server's GIL). Imports only the surrogate library."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import torch

from surrogate.models import Fit, fit_classifier, warm_up


def init_worker(threads: int) -> None:
    """Process initialiser: die with the server, leave the other core to it, pay the
    first-fit cost now. The worker keeps the normal priority: at a lower one, planners that
    keep the cores busy starved it, and they were guided for hundreds of rollouts by fits
    that knew none of their failures (BENCHMARKS.md, "Measurements behind the defaults")."""
    parent = os.getppid()
    threading.Thread(target=_exit_when_orphaned, args=(parent,), daemon=True).start()
    torch.set_num_threads(threads)
    warm_up()


def _exit_when_orphaned(parent: int) -> None:
    """A killed server cannot stop its fit worker, and the worker holds both ends of its
    queues, so it would never see EOF: poll the parent and leave when it is gone."""
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(0)


def fit_job(z: np.ndarray, y: np.ndarray, seed: int, warm: Fit | None, max_inducing: int) -> Fit:
    return fit_classifier(z, y, seed=seed, warm=warm, max_inducing=max_inducing)

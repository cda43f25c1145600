"""GP fits on encoded inputs `Z in [0, 1]^D`, with gpytorch; each returns its frozen NumPy
predictor (`surrogate.predictors`), which is what is served, stored and scored.

- `fit_classifier`: variational GP classifier (Matern 5/2 ARD, constant mean, Bernoulli/probit
  likelihood) with at most `max_inducing` inducing points (k-means initialised), trained on at
  most `max_points` points (the boundary first, then both classes alike), SMOTE against class
  imbalance (unless asked not to), warm start from the previous fit. With one class only or
  fewer than `MIN_POINTS` points it returns the distance prior `PriorPredictor` instead.
- `fit_regression`: exact GP regression (Matern 5/2 ARD, constant mean) for GP-UCB, and for the
  authors' label-regression variant (`fit_label_regression`: GP on +-1 labels, PoF = Phi(mu/sigma)).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import gpytorch
import numpy as np
import torch
from imblearn.over_sampling import SMOTE
from linear_operator.utils.errors import NotPSDError
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial import cKDTree
from scipy.special import ndtri
from sklearn.cluster import KMeans
from sklearn.neighbors import NearestNeighbors
from threadpoolctl import OpenBLASController, threadpool_limits

from surrogate.config import SurrogateConfig
from surrogate.kernels import matern52
from surrogate.predictors import (
    JITTER,
    LabelRegressionPredictor,
    PriorPredictor,
    RegressionPredictor,
    VGPPredictor,
)

MIN_POINTS = 4
BOUNDARY_SHARE = 0.03  # of a subsampled fit's points, at most this many chosen as wrong ones
WARM_LR = 0.03  # Adam's first steps are lr-sized whatever the gradient: small from a warm start
NEIGHBOURS = 8  # without a last fit: whether most of these have the other label
COLD_ITERS = 60  # a fit's steps from `_start_posterior`'s posterior
WARM_ITERS = 33  # ... and from a warm start's
START_SCALE = 1.5  # the start posterior's latent value per probit of a neighbourhood's rate
TRAIN_DTYPE = torch.float32  # the same held-out AUC as float64 at two thirds of the cost
# (a fit whose inducing points are too close for float32 is trained again in float64)


@dataclass
class Fit:
    """One fit: its predictor, what it cost and how well it matches its training labels."""

    kind: str  # "prior" | "vgp" | "label-regression" | "regression"
    predictor: Any
    n_fitted: int
    fit_seconds: float
    iterations: int = 0
    train_accuracy: float | None = None
    lengthscales: list[float] | None = None
    warm_state: dict[str, Any] | None = field(default=None, repr=False)
    n_trained: int | None = None  # points the fit trained on (n_fitted unless subsampled)
    n_inducing: int | None = None


class _SVGP(gpytorch.models.ApproximateGP):
    def __init__(self, inducing: torch.Tensor) -> None:
        dist = gpytorch.variational.CholeskyVariationalDistribution(inducing.shape[0])
        strategy = gpytorch.variational.VariationalStrategy(
            self, inducing, dist, learn_inducing_locations=True, jitter_val=JITTER
        )
        super().__init__(strategy)
        self.mean_module = gpytorch.means.ConstantMean()
        self.covar_module = gpytorch.kernels.ScaleKernel(
            gpytorch.kernels.MaternKernel(nu=2.5, ard_num_dims=inducing.shape[1])
        )

    def forward(self, x: torch.Tensor) -> gpytorch.distributions.MultivariateNormal:
        return gpytorch.distributions.MultivariateNormal(self.mean_module(x), self.covar_module(x))


_threads_lock = threading.Lock()


def use_threads(n: int) -> None:
    """Run this process's torch and BLAS on `n` threads, and the OpenMP of the calling thread
    (scikit-learn's k-means, torch) on as many. The service computes in many threads at once
    (a request each, the instant lane) and its fit worker beside them: threads of BLAS's own on
    top spin for cores that others hold, and on a loaded machine a suggestion's matrix
    products cost several times the CPU (BENCHMARKS.md, "Hard problems")."""
    torch.set_num_threads(n)
    # OpenBLAS's pool is the process's: threadpoolctl lets one thread set it, the first that
    # tries (scikit-learn's own limits, in a fit, may have been first).
    OpenBLASController.clear_controlling_thread(force=True)
    threadpool_limits(n)


@contextmanager
def _single_thread() -> Iterator[None]:
    """Fits are small (m <= a few hundred): one torch thread is as fast, and on a shared,
    oversubscribed machine OpenMP spinning across threads makes fits several times slower."""
    with _threads_lock:
        before = torch.get_num_threads()
        torch.set_num_threads(1)
    try:
        yield
    finally:
        with _threads_lock:
            torch.set_num_threads(before)


def _train(
    loss_fn: Any,
    params: list[torch.Tensor],
    max_iters: int,
    lr: float,
    tol: float = 1e-3,
    patience: int = 20,
) -> int:
    """Adam on `loss_fn()` until the loss stops improving by `tol` (relative) for `patience`."""
    optimiser = torch.optim.Adam(params, lr=lr)
    with _single_thread():
        return _adam_loop(loss_fn, optimiser, max_iters, tol, patience)


def _adam_loop(
    loss_fn: Any, optimiser: torch.optim.Optimizer, max_iters: int, tol: float, patience: int
) -> int:
    best = np.inf
    since_best = 0
    for it in range(1, max_iters + 1):
        optimiser.zero_grad()
        loss = loss_fn()
        loss.backward()
        optimiser.step()
        value = float(loss.detach())
        if not np.isfinite(best) or value < best - tol * max(1.0, abs(best)):
            best, since_best = value, 0
        else:
            since_best += 1
            if since_best >= patience:
                return it
    return max_iters


def _balance(z: np.ndarray, y: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """SMOTE the minority class up to the majority when it is under half of it."""
    counts = np.bincount(y.astype(int), minlength=2)
    minority = int(counts.min())
    if minority < 2 or minority >= 0.5 * counts.max():
        return z, y
    smote = SMOTE(k_neighbors=min(5, minority - 1), random_state=seed)
    zb, yb = smote.fit_resample(z, y.astype(int))
    return np.asarray(zb, dtype=float), np.asarray(yb, dtype=bool)


def _training_subset(z: np.ndarray, y: np.ndarray, budget: int, seed: int, last: Any) -> np.ndarray:
    """Indices of at most `budget` points to train on (all of them if they fit).

    First the points that matter most, up to `BOUNDARY_SHARE` of the budget: those the `last`
    fit got wrong (without a last fit: those whose nearest neighbours in a random pool mostly
    have the other label). Then both classes alike, so that the minority keeps all its points
    up to half of what is left and SMOTE has what it needs to balance the rest. Each point draws
    one random key for good (a stream seeded by `seed`, so a point keeps its key as the type
    grows): the same points stay in from one refit to the next and a warm start stays close.
    """
    n = len(y)
    if budget <= 0 or n <= budget:
        return np.arange(n)
    keys = np.random.default_rng(seed).random(n)
    chosen = np.zeros(n, dtype=bool)
    if last is not None:
        candidates = np.arange(n)
        margin = (last.proba(z) - 0.5) * np.where(y, 1.0, -1.0)
    else:
        candidates = np.argsort(keys)[: 4 * budget]
        k = min(NEIGHBOURS, len(candidates) - 1)
        near = NearestNeighbors(n_neighbors=k + 1).fit(z[candidates])
        _, idx = near.kneighbors(z[candidates])
        margin = 0.5 - (y[candidates][idx[:, 1:]] != y[candidates][:, None]).mean(axis=1)
    order = np.argsort(margin, kind="stable")[: int(budget * BOUNDARY_SHARE)]
    chosen[candidates[order[margin[order] < 0.0]]] = True
    minority = bool(y.sum() * 2 < n)
    for label in (minority, not minority):
        pool = np.flatnonzero(~chosen & (y == label))
        left = budget - int(chosen.sum())
        take = min(len(pool), left // 2 if label == minority else left)
        chosen[pool[np.argsort(keys[pool], kind="stable")[:take]]] = True
    return np.flatnonzero(chosen)


def _kmeans_centres(z: np.ndarray, m: int, seed: int) -> np.ndarray:
    unique = np.unique(z, axis=0)
    if len(unique) <= m:
        return unique
    km = KMeans(n_clusters=m, n_init=1, max_iter=50, random_state=seed).fit(unique)
    return km.cluster_centers_


def _start_posterior(model: _SVGP, z: np.ndarray, y: np.ndarray) -> None:
    """Start a fit's variational mean where its points say rather than at the prior's zero:
    each inducing point's latent value is `START_SCALE` probits of the feasible rate of the
    training points nearest to it (smoothed by half a point each way), smoothed and whitened
    through the starting kernel. Adam then spends its steps on the boundary and the length
    scales, not on climbing from zero everywhere. In float64 whatever the training precision."""
    strategy = model.variational_strategy
    inducing = strategy.inducing_points.detach().numpy().astype(float)
    nearest = cKDTree(inducing).query(z)[1]
    counts = np.bincount(nearest, minlength=len(inducing))
    feasible = np.bincount(nearest, weights=y.astype(float), minlength=len(inducing))
    latent = START_SCALE * ndtri((feasible + 0.5) / (counts + 1.0))
    kzz = _kernel(model, inducing)
    eye = np.eye(len(inducing))
    constant = float(model.mean_module.constant.detach())
    # The ridge fit of the latent values, u = K (K + s I)^-1 t with s the prior's variance (the
    # rates are noisy), whitened: L^-1 u = L^T (K + s I)^-1 t, bounded however close the
    # inducing points (L^-1 t alone grows without bound where K is nearly singular).
    ridge = cho_solve(cho_factor(kzz + np.diag(kzz).max() * eye, lower=True), latent - constant)
    whitened = np.linalg.cholesky(kzz + JITTER * eye).T @ ridge
    with torch.no_grad():
        strategy._variational_distribution.variational_mean.copy_(torch.as_tensor(whitened))
        strategy.variational_params_initialized.fill_(1)


def _trained(
    inducing: torch.Tensor,
    state: dict[str, Any] | None,
    z: np.ndarray,
    y: np.ndarray,
    steps: int,
    lr: float,
    dtype: torch.dtype,
) -> tuple[_SVGP, int]:
    """A classifier trained on `z`, `y` in `dtype`, from the `state` of a last fit with as many
    inducing points, else from its kernel (if any) and `_start_posterior`; and its steps."""
    model = _SVGP(inducing.to(dtype)).to(dtype)
    likelihood = gpytorch.likelihoods.BernoulliLikelihood().to(dtype)
    if state is not None and state["m"] == len(inducing):
        model.load_state_dict(state["model"])
    else:
        if state is not None:  # the last fit's kernel, a posterior anew
            for name in ("mean_module", "covar_module"):
                prefix = name + "."
                part = {
                    k[len(prefix) :]: v for k, v in state["model"].items() if k.startswith(prefix)
                }
                getattr(model, name).load_state_dict(part)
        _start_posterior(model, z, y)
    tx = torch.as_tensor(z, dtype=dtype)
    ty = torch.as_tensor(y.astype(float), dtype=dtype)
    model.train()
    likelihood.train()
    elbo = gpytorch.mlls.VariationalELBO(likelihood, model, num_data=len(ty))
    params = [*model.parameters(), *likelihood.parameters()]
    return model, _train(lambda: -elbo(model(tx), ty), params, steps, lr)


def fit_classifier(
    z: np.ndarray,
    y: np.ndarray,
    *,
    seed: int = 0,
    warm: Fit | None = None,
    max_inducing: int = SurrogateConfig().max_inducing,
    max_points: int = SurrogateConfig().max_fit_points,
    max_iters: int = COLD_ITERS,
    warm_iters: int = WARM_ITERS,
    lr: float = 0.1,
    balance: bool = SurrogateConfig().balance_classes,
) -> Fit:
    """Fit P(feasible | z) on `z (n, D)`, `y (n,)` bool (True = feasible), on classes
    SMOTE-balanced if `balance`.

    At most `max_points` of them are trained on (`_training_subset`; 0: all), so that a fit of
    a large type costs what one of `max_points` does.

    Training runs in float32 from a posterior the points suggest (`_start_posterior`): the
    default steps and rate are the cheapest that reach the held-out AUC of a longer, slower fit
    (BENCHMARKS.md, "Hard problems"): a transfer target waits for its predecessors' fits, and a
    new type of thousands of points for its first.

    A `warm` fit of the same kind starts the optimiser from its hyper-parameters, inducing
    locations and variational posterior (when the inducing count is unchanged), so a refit after
    a few new points takes a fraction of a cold one.
    """
    t0 = time.perf_counter()
    z = np.asarray(z, dtype=float)
    y = np.asarray(y, dtype=bool)
    if len(z) != len(y):
        raise ValueError(f"{len(z)} points and {len(y)} labels")
    if len(y) < MIN_POINTS or y.all() or not y.any():
        prior = PriorPredictor(feasible=z[y], infeasible=z[~y])
        return Fit("prior", prior, len(y), time.perf_counter() - t0)
    torch.manual_seed(seed)
    state = warm.warm_state if warm is not None and warm.kind == "vgp" else None
    last = warm.predictor if warm is not None and state is not None else None
    subset = _training_subset(z, y, max_points, seed, last)
    zb, yb = _balance(z[subset], y[subset], seed) if balance else (z[subset], y[subset])
    m = min(max_inducing, len(np.unique(zb, axis=0)))
    if state is not None and state["m"] == m:
        inducing = torch.as_tensor(state["model"]["variational_strategy.inducing_points"])
    else:
        inducing = torch.as_tensor(_kmeans_centres(zb, m, seed))
    reused = state is not None and state["m"] == m
    steps = warm_iters if reused else max_iters  # a new inducing set starts its posterior anew
    rate = min(lr, WARM_LR) if reused else lr
    try:
        model, iters = _trained(inducing, state, zb, yb, steps, rate, TRAIN_DTYPE)
    except NotPSDError:  # points too close for float32's precision
        torch.manual_seed(seed)
        model, iters = _trained(inducing, state, zb, yb, steps, rate, torch.float64)
    model = model.double()  # served, scored and stored in float64
    predictor = _vgp_predictor(model)
    accuracy = float(((predictor.proba(z[subset]) > 0.5) == y[subset]).mean())  # trained on
    weights = {k: v.detach().clone() for k, v in model.state_dict().items()}
    warm_state = {"m": m, "model": weights}
    return Fit(
        "vgp",
        predictor,
        len(y),
        time.perf_counter() - t0,
        iters,
        accuracy,
        predictor.lengthscale.tolist(),
        warm_state,
        len(subset),
        m,
    )


def _scaled(kernel: Any) -> tuple[np.ndarray, float]:
    """A ScaleKernel(Matern)'s lengthscales `(d,)` and outputscale."""
    lengthscale = kernel.base_kernel.lengthscale.detach().numpy().reshape(-1).astype(float)
    return lengthscale, float(kernel.outputscale)


def _kernel(model: _SVGP, x: np.ndarray) -> np.ndarray:
    """The model's prior covariance of `x` with itself, in float64."""
    with torch.no_grad():
        lengthscale, outputscale = _scaled(model.covar_module)
    return matern52(x, x, lengthscale, outputscale)


def _vgp_predictor(model: _SVGP) -> VGPPredictor:
    with torch.no_grad():
        strategy = model.variational_strategy
        inducing = strategy.inducing_points.detach().numpy().astype(float)
        dist = strategy._variational_distribution
        m_v = dist.variational_mean.detach().numpy().astype(float)
        chol_s = dist.chol_variational_covar.detach().numpy().astype(float)
        lengthscale, outputscale = _scaled(model.covar_module)
    constant = float(model.mean_module.constant.detach())
    kzz = matern52(inducing, inducing, lengthscale, outputscale) + JITTER * np.eye(len(inducing))
    l_inv = np.linalg.inv(np.linalg.cholesky(kzz))
    s = np.tril(chol_s) @ np.tril(chol_s).T
    a = l_inv.T @ m_v
    b = l_inv.T @ (s - np.eye(len(inducing))) @ l_inv
    return VGPPredictor(inducing, lengthscale, outputscale, constant, a, b)


class _ExactGP(gpytorch.models.ExactGP):
    def __init__(self, x: torch.Tensor, y: torch.Tensor, likelihood: Any) -> None:
        super().__init__(x, y, likelihood)
        self.mean_module = gpytorch.means.ConstantMean()
        self.covar_module = gpytorch.kernels.ScaleKernel(
            gpytorch.kernels.MaternKernel(nu=2.5, ard_num_dims=x.shape[1])
        )

    def forward(self, x: torch.Tensor) -> gpytorch.distributions.MultivariateNormal:
        return gpytorch.distributions.MultivariateNormal(self.mean_module(x), self.covar_module(x))


def fit_regression(
    z: np.ndarray,
    y: np.ndarray,
    *,
    seed: int = 0,
    warm: Fit | None = None,
    standardize: bool = True,
    max_iters: int = 150,
    lr: float = 0.1,
) -> Fit:
    """Exact GP regression of `y (n,)` on `z (n, D)` (n >= 1), hyper-parameters by marginal
    likelihood; `warm` starts from an earlier regression fit's hyper-parameters. O(n^3): meant for
    task-local data sets of a few hundred points."""
    t0 = time.perf_counter()
    z = np.asarray(z, dtype=float)
    y = np.asarray(y, dtype=float)
    shift, scale = 0.0, 1.0
    if standardize:
        shift = float(y.mean())
        scale = float(y.std()) if len(y) > 1 and y.std() > 1e-12 else 1.0
    targets = (y - shift) / scale
    torch.manual_seed(seed)
    tx, ty = torch.as_tensor(z), torch.as_tensor(targets)
    likelihood = gpytorch.likelihoods.GaussianLikelihood(
        noise_constraint=gpytorch.constraints.GreaterThan(1e-5)
    ).double()
    model = _ExactGP(tx, ty, likelihood).double()
    state = warm.warm_state if warm is not None and warm.kind == fit_kind(standardize) else None
    if state is not None:
        model.load_state_dict(state["model"])
    model.train()
    likelihood.train()
    mll = gpytorch.mlls.ExactMarginalLogLikelihood(likelihood, model)
    iters = 0
    if len(y) > 1:
        iters = _train(
            lambda: -mll(model(tx), ty),
            list(model.parameters()),
            max_iters if state is None else max_iters // 3,
            lr,
        )
    with torch.no_grad():
        lengthscale = model.covar_module.base_kernel.lengthscale.numpy().reshape(-1).copy()
        outputscale = float(model.covar_module.outputscale)
        noise = float(likelihood.noise)
        constant = float(model.mean_module.constant)
    k = matern52(z, z, lengthscale, outputscale) + (noise + JITTER) * np.eye(len(z))
    chol_inv = np.linalg.inv(np.linalg.cholesky(k))
    alpha = chol_inv.T @ (chol_inv @ (targets - constant))
    predictor = RegressionPredictor(
        z.copy(), lengthscale, outputscale, constant, noise, alpha, chol_inv, shift, scale
    )
    warm_state = {"model": {k: v.detach().clone() for k, v in model.state_dict().items()}}
    return Fit(
        fit_kind(standardize),
        predictor,
        len(y),
        time.perf_counter() - t0,
        iters,
        None,
        lengthscale.tolist(),
        warm_state,
    )


def fit_kind(standardize: bool) -> str:
    return "regression" if standardize else "label-regression"


def fit_label_regression(
    z: np.ndarray, y: np.ndarray, *, seed: int = 0, warm: Fit | None = None
) -> Fit:
    """The authors' variant of the classifier: GP regression on +-1 labels, PoF = Phi(mu/sigma)."""
    y = np.asarray(y, dtype=bool)
    if len(y) < MIN_POINTS or y.all() or not y.any():
        return fit_classifier(z, y, seed=seed)
    fit = fit_regression(z, np.where(y, 1.0, -1.0), seed=seed, warm=warm, standardize=False)
    fit.predictor = LabelRegressionPredictor(fit.predictor)
    fit.train_accuracy = float(((fit.predictor.proba(np.asarray(z)) > 0.5) == y).mean())
    return fit


def warm_up(seed: int = 0) -> float:
    """Pay the first-fit cost of a fresh process (torch/gpytorch lazy initialisation, several
    seconds) on a toy problem; returns the seconds it took. Call once at start."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    z = rng.random((16, 2))
    y = z[:, 0] > 0.5
    fit_classifier(z, y, seed=seed, max_iters=20)
    fit_regression(z, z[:, 1], seed=seed, max_iters=20)
    return time.perf_counter() - t0

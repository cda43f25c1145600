"""Additive kernel terms over one decision's columns of a type's GP input.

A type's classifier has one ARD Matern kernel over all its inputs, so a failure lowers
P(feasible) only near itself in every input at once: twenty placements that all fail with the
top grasp teach it "not here, with the top grasp" twenty times, and the next placement far from
them is rated 0.5 again. With a term per decision beside it, `k = k_all + sum_g k_g` (the mixed
kernel of CoCaBO, Ru et al. 2020, a sum beside the product), the latent function also has a part
that depends on one decision alone, which a few failures spread over the other inputs can set:
"the top grasp fails wherever it places". The fit chooses each term's outputscale, so a type
whose feasibility depends on all its inputs together can turn the terms down.

`SurrogateConfig.additive` (the service's `CPKB_SURROGATE__ADDITIVE`) says which decisions get
a term: `none`, the categorical ones (`choices`: grasps, sides), or every decision
(`decisions`). A type with one decision gets none: its term would repeat the main kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import get_args

import numpy as np

from surrogate.config import AdditiveMode
from surrogate.domains import CategoricalDomain
from surrogate.encoding import SpaceEncoder
from surrogate.kernels import matern52

ADDITIVE_MODES: tuple[str, ...] = get_args(AdditiveMode)
Groups = tuple[tuple[int, ...], ...]


@dataclass(frozen=True)
class AdditiveTerm:
    """One term `outputscale * Matern52(z[:, dims] / lengthscale)`."""

    dims: np.ndarray  # (d,) columns of Z (whole numbers, kept as floats for the snapshot)
    lengthscale: np.ndarray  # (d,)
    outputscale: float


def term_groups(encoder: SpaceEncoder, mode: AdditiveMode | str) -> Groups:
    """The column groups that get a term of their own under `mode`."""
    if mode not in ADDITIVE_MODES:
        raise ValueError(f"additive terms: {mode!r} is not one of {', '.join(ADDITIVE_MODES)}")
    if mode == "none" or len(encoder.vars) < 2:
        return ()
    chosen = [
        var
        for var in encoder.vars
        if var.in_z and (mode == "decisions" or isinstance(var.domain, CategoricalDomain))
    ]
    return tuple(tuple(range(var.start, var.start + var.z_width)) for var in chosen)


def additive_cov(x: np.ndarray, z: np.ndarray, terms: tuple[AdditiveTerm, ...]) -> np.ndarray:
    """The terms' covariance between rows of `x (n, D)` and `z (m, D)` -> `(n, m)`."""
    out = np.zeros((len(x), len(z)))
    for term in terms:
        dims = term.dims.astype(int)
        out += matern52(x[:, dims], z[:, dims], term.lengthscale, term.outputscale)
    return out


def terms_variance(terms: tuple[AdditiveTerm, ...]) -> float:
    """The terms' prior variance at any point (Matern is 1 at distance 0)."""
    return float(sum(term.outputscale for term in terms))

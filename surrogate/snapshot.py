"""Predictors as JSON, so that a planner can evaluate MPF in its own process.

Every predictor the service answers with is a small tree of frozen numpy dataclasses (a fit,
the stated prior, and the `RecentPoints` / `UnseenChoices` wrappers around them). `dump` turns one
into plain JSON (arrays as base64 little-endian float64 with their shape, so that a 128 x 128
variational term costs 175 kB rather than a list of 16,384 decimals), `load` rebuilds it exactly:
a loaded predictor answers the same P(feasible) to the last bit. `model_to_json` and
`model_from_json` carry a whole `TypeModel` (the wire contract's `ModelSnapshot`).
"""

from __future__ import annotations

import base64
from collections.abc import Mapping
from typing import Any

import numpy as np

from surrogate.domains import space_from_json, space_to_json
from surrogate.predictors import (
    FeasibilityPredictor,
    LabelRegressionPredictor,
    PriorPredictor,
    RecentPoints,
    RegressionPredictor,
    UnseenChoices,
    VGPPredictor,
)
from surrogate.suggest import TypeModel

Snapshot = dict[str, Any]


class SnapshotError(ValueError):
    """A snapshot that does not describe a predictor this version knows."""


def _array(a: np.ndarray) -> dict[str, Any]:
    data = np.ascontiguousarray(a, dtype="<f8")
    return {"shape": list(data.shape), "data": base64.b64encode(data.tobytes()).decode("ascii")}


def _unarray(obj: Any, where: str) -> np.ndarray:
    try:
        raw = base64.b64decode(obj["data"], validate=True)
        return np.frombuffer(raw, dtype="<f8").reshape(obj["shape"]).copy()
    except (KeyError, TypeError, ValueError) as exc:
        raise SnapshotError(f"{where}: not an encoded array ({exc})") from exc


def _regression(r: RegressionPredictor) -> Snapshot:
    return {
        "train": _array(r.train),
        "lengthscale": _array(r.lengthscale),
        "outputscale": r.outputscale,
        "constant": r.constant,
        "noise": r.noise,
        "alpha": _array(r.alpha),
        "chol_inv": _array(r.chol_inv),
        "y_shift": r.y_shift,
        "y_scale": r.y_scale,
    }


def dump(predictor: FeasibilityPredictor) -> Snapshot:
    """The JSON form of a predictor; TypeError for a kind this module does not know."""
    match predictor:
        case PriorPredictor():
            return {
                "kind": "prior",
                "feasible": _array(predictor.feasible),
                "infeasible": _array(predictor.infeasible),
            }
        case RecentPoints():
            return {
                "kind": "recent",
                "base": dump(predictor.base),
                "feasible": _array(predictor.feasible),
                "infeasible": _array(predictor.infeasible),
            }
        case UnseenChoices():
            return {
                "kind": "unseen",
                "base": dump(predictor.base),
                "prior": dump(predictor.prior),
                "seen": [
                    {"start": s.start, "stop": s.stop, "rows": _array(rows)}
                    for s, rows in predictor.seen
                ],
            }
        case VGPPredictor():
            return {
                "kind": "vgp",
                "inducing": _array(predictor.inducing),
                "lengthscale": _array(predictor.lengthscale),
                "outputscale": predictor.outputscale,
                "constant": predictor.constant,
                "a": _array(predictor.a),
                "b": _array(predictor.b),
            }
        case LabelRegressionPredictor():
            return {"kind": "label-regression", "regression": _regression(predictor.regression)}
    raise TypeError(f"cannot snapshot a {type(predictor).__name__}")


def load(snapshot: Any, where: str = "predictor") -> FeasibilityPredictor:
    """The predictor `dump` wrote; SnapshotError naming the part that is wrong."""
    if not isinstance(snapshot, dict):
        raise SnapshotError(f"{where}: not an object")
    kind = snapshot.get("kind")
    try:
        if kind == "prior":
            return PriorPredictor(
                _unarray(snapshot["feasible"], f"{where}.feasible"),
                _unarray(snapshot["infeasible"], f"{where}.infeasible"),
            )
        if kind == "recent":
            return RecentPoints(
                load(snapshot["base"], f"{where}.base"),
                _unarray(snapshot["feasible"], f"{where}.feasible"),
                _unarray(snapshot["infeasible"], f"{where}.infeasible"),
            )
        if kind == "unseen":
            seen = tuple(
                (slice(int(s["start"]), int(s["stop"])), _unarray(s["rows"], f"{where}.seen"))
                for s in snapshot["seen"]
            )
            return UnseenChoices(
                load(snapshot["base"], f"{where}.base"),
                load(snapshot["prior"], f"{where}.prior"),
                seen,
            )
        if kind == "vgp":
            if snapshot.get("terms"):  # a fit of the retired `surrogate.additive` kernel
                raise SnapshotError(f"{where}: a vgp with additive kernel terms (retired)")
            return VGPPredictor(
                _unarray(snapshot["inducing"], f"{where}.inducing"),
                _unarray(snapshot["lengthscale"], f"{where}.lengthscale"),
                float(snapshot["outputscale"]),
                float(snapshot["constant"]),
                _unarray(snapshot["a"], f"{where}.a"),
                _unarray(snapshot["b"], f"{where}.b"),
            )
        if kind == "label-regression":
            r = snapshot["regression"]
            regression = RegressionPredictor(
                _unarray(r["train"], f"{where}.train"),
                _unarray(r["lengthscale"], f"{where}.lengthscale"),
                float(r["outputscale"]),
                float(r["constant"]),
                float(r["noise"]),
                _unarray(r["alpha"], f"{where}.alpha"),
                _unarray(r["chol_inv"], f"{where}.chol_inv"),
                float(r["y_shift"]),
                float(r["y_scale"]),
            )
            return LabelRegressionPredictor(regression)
    except (KeyError, TypeError) as exc:
        raise SnapshotError(f"{where}: {kind} snapshot lacks {exc}") from exc
    raise SnapshotError(f"{where}: unknown predictor kind {kind!r}")


def model_to_json(type_id: str, model: TypeModel) -> dict[str, Any]:
    """A type's model in the wire contract's `ModelSnapshot` form."""
    return {
        "type_id": type_id,
        "version": model.version,
        "space": space_to_json(model.space),
        "n_points": model.n_points,
        "n_fitted": model.n_fitted,
        "predictor": dump(model.predictor),
    }


def model_from_json(obj: Mapping[str, Any]) -> tuple[str, TypeModel]:
    """The type ID and model `model_to_json` wrote; SnapshotError naming the part that is wrong."""
    try:
        space = space_from_json(obj["space"])
        model = TypeModel(
            space,
            load(obj["predictor"]),
            str(obj["version"]),
            int(obj["n_fitted"]),
            int(obj["n_points"]),
        )
        return str(obj["type_id"]), model
    except SnapshotError:
        raise
    except (KeyError, TypeError, ValueError) as exc:  # DomainError is a ValueError
        raise SnapshotError(f"model snapshot: {exc}") from exc

"""Choosing the heat map's axes: by the fit's lengthscales, named per dimension."""

from __future__ import annotations

from pydantic import TypeAdapter

from contract.models import Domain
from server.dashboard.heatmap import continuous_dims
from server.dashboard.views import choose_dims, dim_lengthscales

SPACE = TypeAdapter(dict[str, Domain]).validate_python(
    {
        "#dir": {"kind": "categorical", "choices": ["front", "top"]},
        "#pose": {"kind": "continuous", "low": [0.0, 0.0, 0.0], "high": [1.0, 1.0, 1.0]},
    }
)


def test_lengthscales_are_named_by_the_encoders_columns() -> None:
    # one-hot #dir takes columns 0-1, #pose 2-4
    named = dim_lengthscales(SPACE, [9.0, 9.0, 3.0, 2.0, 0.1])
    assert named == {"#pose[0]": 3.0, "#pose[1]": 2.0, "#pose[2]": 0.1}
    assert dim_lengthscales(SPACE, [1.0, 2.0]) == {}
    assert dim_lengthscales(SPACE, None) == {}


def test_default_axes_are_the_shortest_lengthscales_and_a_request_wins() -> None:
    dims = continuous_dims(SPACE)
    relevance = {"#pose[0]": 3.0, "#pose[1]": 2.0, "#pose[2]": 0.1}
    dx, dy = choose_dims(dims, None, None, relevance)
    assert (dx.name, dy.name) == ("#pose[2]", "#pose[1]")
    dx, dy = choose_dims(dims, "#pose[0]", None, relevance)
    assert (dx.name, dy.name) == ("#pose[0]", "#pose[2]")
    dx, dy = choose_dims(dims, None, None)
    assert (dx.name, dy.name) == ("#pose[0]", "#pose[1]")

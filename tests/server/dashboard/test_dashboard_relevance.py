"""Relevance named by the encoder's columns, refreshed with the page's poll, and a fit that
gets its own training points wrong flagged (issue 56.2)."""

from __future__ import annotations

import re
from typing import Any

from pydantic import TypeAdapter

from contract.models import Domain, SurrogateState
from server.dashboard.views import fit_columns
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder
from tests.service_support import make_graph, make_point

PLACEMENT = {
    "kind": "continuous",
    "low": [0.0, 0.0, -3.1416],
    "high": [1.0, 1.0, 3.1416],
    "frame": "table",
    "heading": 2,
    "periodic": True,
}


def test_every_column_of_the_encoding_has_a_name() -> None:
    space = space_from_json(
        {
            "#dir": {"kind": "categorical", "choices": ["front", "top"]},
            "#a": PLACEMENT,
            "#b": PLACEMENT,
            "#gap": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0], "frame": "w"},
            "#gap2": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0], "frame": "w"},
        }
    )
    encoder = SpaceEncoder(space)
    names = encoder.column_names()
    assert len(names) == encoder.dim and all(names) and len(set(names)) == len(names)
    assert names[:2] == ["#dir=front", "#dir=top"]
    assert "#a[2] cos" in names and "#a[2] sin" in names
    assert "#a~#b turn" in names and "#a~#b x in b" in names
    assert "|#gap-#gap2|[1]" in names


def test_a_choices_only_type_has_its_lengthscales_named() -> None:
    raw = {"#dir": {"kind": "categorical", "choices": ["a", "b", "c"]}}
    space = TypeAdapter(dict[str, Domain]).validate_python(raw)
    columns, why = fit_columns(space, [0.5, 2.0, 1.0])
    assert why is None and columns == [("#dir=a", 0.5), ("#dir=c", 1.0), ("#dir=b", 2.0)]
    columns, why = fit_columns(space, [0.5, 2.0])
    assert columns == [] and "2 lengthscales" in why and "3 columns" in why


def _state(lengthscales: list[float], accuracy: float, version: int) -> SurrogateState:
    return SurrogateState(
        status="ready",
        version=version,
        n_fitted=12,
        lengthscales=lengthscales,
        train_accuracy=accuracy,
    )


def test_the_poll_carries_relevance_and_axes_of_the_newest_fit(core_client: Any) -> None:
    graph = make_graph("Inv-kin", ("box1",))
    points = [make_point(i, graph=graph) for i in range(12)]
    results = core_client.post("/v1/kbs/default/points", json={"points": points}).json()
    type_id = results["results"][0]["type_id"]
    url = f"/ui/api/kbs/default/types/{type_id}"
    none_yet = core_client.get(url).json()["fragments"]["relevance-panel"]
    assert "No fit yet" in none_yet

    detail = core_client.get(f"/v1/kbs/default/types/{type_id}").json()
    space = space_from_json(detail["space"])
    names = SpaceEncoder(space).column_names()
    pose = [names.index(f"#pose[{i}]") for i in range(3)]
    fits: dict[str, SurrogateState] = {}
    core_client.app.state.hooks.surrogate = lambda kb, t: fits.get(t)

    first = [5.0] * len(names)
    first[pose[0]], first[pose[1]] = 0.1, 0.2
    fits[type_id] = _state(first, 1.0, 1)
    data = core_client.get(url).json()
    panel = data["fragments"]["relevance-panel"]
    assert 'data-column="#pose[0]"' in panel and 'data-column="#dir=' in panel
    assert panel.index("#pose[0]") < panel.index("#pose[1]") < panel.index("#dir=")
    assert "accuracy-warning" not in panel
    assert (data["x_dim"], data["y_dim"]) == ("#pose[0]", "#pose[1]")

    second = [5.0] * len(names)
    second[pose[2]], second[pose[1]] = 0.05, 0.3
    fits[type_id] = _state(second, 0.9, 2)
    data = core_client.get(url).json()
    assert (data["x_dim"], data["y_dim"]) == ("#pose[2]", "#pose[1]")
    assert "<option selected>#pose[2]</option>" in data["fragments"]["dims-panel"]
    assert "fit v2" in data["fragments"]["relevance-panel"]
    warning = data["fragments"]["relevance-panel"]
    assert 'id="accuracy-warning"' in warning and "90.0%" in warning
    # the page's heat map follows the fit when its axes were not chosen
    page = core_client.get(f"/ui/kbs/default/types/{type_id}").text
    src = re.search(r'/heatmap\.svg\?([^"]*)"', page)
    assert src and "x=" not in src.group(1)
    chosen = core_client.get(f"/ui/kbs/default/types/{type_id}", params={"x": "#pose[1]"}).text
    src = re.search(r'/heatmap\.svg\?([^"]*)"', chosen)
    assert src and "&amp;x=%23pose%5B1%5D" in src.group(1)

"""`cpkb types` tells apart types whose failure, decisions and context are the same."""

from __future__ import annotations

from service_support import DIR_DOMAIN, POSE_DOMAIN, make_graph

from contract.models import TypeDetail
from cpkb.cli.service import _differences, _short_ids


def _detail(type_id: str, graph: dict) -> TypeDetail:
    return TypeDetail(
        type_id=type_id,
        failure=next(n["label"] for n in graph["nodes"] if n["role"] == "failure"),
        decisions=["#dir", "#pose"],
        context=["box1"],
        n_points=3,
        n_infeasible=1,
        graph=graph,
        space={"#dir": DIR_DOMAIN, "#pose": POSE_DOMAIN},
    )


def test_alike_types_are_told_apart_by_the_edges_only_they_have() -> None:
    plain = make_graph()
    wider = make_graph(pose_domain={**POSE_DOMAIN, "high": [2.0, 1.0, 3.0]})
    other = make_graph()
    other["edges"][0]["label"] = "approach"
    unlike = make_graph(failure="Plan-motion")
    details = [_detail("a1", plain), _detail("b2", other), _detail("c3", unlike)]
    differences = _differences(details)
    assert differences == {"a1": "#dir -grasp-> Inv-kin", "b2": "#dir -approach-> Inv-kin"}
    assert _differences([_detail("a1", plain), _detail("d4", wider)]) == {
        "a1": "domains or repeated edges",
        "d4": "domains or repeated edges",
    }
    assert _differences([_detail("a1", plain)]) == {}


def test_short_ids_stay_distinct() -> None:
    ids = ["18cf81a99ad0e623", "18cf81a9ffffffff", "eae1065e9193ba45"]
    short = _short_ids(ids)
    assert len(set(short.values())) == 3
    assert short["eae1065e9193ba45"] == "eae1065e9" and all(len(v) == 9 for v in short.values())

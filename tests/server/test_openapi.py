"""The OpenAPI document at /openapi.json: the errors each route can answer, in one declared
shape, field descriptions and working examples on the request models, the CSV route's type."""

from __future__ import annotations

from typing import Any

import pytest

from contract import bindings, models
from server.api.responses import ErrorOut, ValidationErrorOut
from tests.service_support import make_point

REQUEST_MODELS = (
    models.KnowledgeBaseIn,
    models.PointsIn,
    models.PointIn,
    models.Graph,
    models.Node,
    models.Edge,
    models.Source,
    models.MatchIn,
    models.PointsSinceIn,
    bindings.BindingIn,
    models.PredictIn,
    models.SuggestIn,
    models.Constraint,
    models.ModelsIn,
)
EXAMPLED = (
    "KnowledgeBaseIn",
    "PointsIn",
    "PointIn",
    "Graph",
    "MatchIn",
    "PointsSinceIn",
    "BindingIn",
    "PredictIn",
    "SuggestIn",
    "ModelsIn",
)


@pytest.fixture
def spec(app_client: Any) -> dict[str, Any]:
    response = app_client.get("/openapi.json")
    assert response.status_code == 200
    return response.json()


def _operations(spec: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    return [
        (method.upper(), path, op)
        for path, ops in spec["paths"].items()
        for method, op in ops.items()
        if path.startswith("/v1/")
    ]


def _schema_ref(response: dict[str, Any]) -> str:
    return response["content"]["application/json"]["schema"]["$ref"].rsplit("/", 1)[-1]


def test_every_route_declares_the_errors_it_can_answer(spec: dict[str, Any]) -> None:
    operations = _operations(spec)
    assert len(operations) >= 14
    for method, path, op in operations:
        codes = set(op["responses"])
        where = f"{method} {path}"
        assert {"401", "503"} <= codes, where
        if "{kb}" in path:
            assert {"404", "422"} <= codes, where
        if method == "POST":
            assert {"400", "413", "422"} <= codes, where
    conflicts = {(m, p) for m, p, op in operations if "409" in op["responses"]}
    assert {
        ("POST", "/v1/kbs"),
        ("POST", "/v1/kbs/{kb}/points"),
        ("POST", "/v1/kbs/{kb}/types/match"),
    } <= conflicts
    assert "503" in spec["paths"]["/healthz"]["get"]["responses"]


def test_errors_share_one_schema_with_a_described_detail(spec: dict[str, Any]) -> None:
    for method, path, op in _operations(spec):
        for code, response in op["responses"].items():
            if code.startswith(("4", "5")):
                expected = "ValidationErrorOut" if code == "422" else "ErrorOut"
                assert _schema_ref(response) == expected, f"{method} {path} {code}"
                assert response["description"], f"{method} {path} {code}"
    schemas = spec["components"]["schemas"]
    detail = schemas["ErrorOut"]["properties"]["detail"]
    assert detail["type"] == "string" and detail["description"]
    assert "detail" in schemas["ValidationErrorOut"]["required"]
    assert "Retry-After" in spec["paths"]["/v1/kbs"]["get"]["responses"]["503"]["headers"]


def test_the_answers_have_the_declared_shapes(app_client: Any) -> None:
    missing = app_client.get("/v1/kbs/nope")
    assert missing.status_code == 404
    assert ErrorOut.model_validate(missing.json()).detail == "knowledge base 'nope' not found"
    assert app_client.post("/v1/kbs", json={"name": "twice"}).status_code == 201
    taken = app_client.post("/v1/kbs", json={"name": "twice"})
    assert taken.status_code == 409 and ErrorOut.model_validate(taken.json()).detail
    invalid = app_client.post("/v1/kbs", json={"name": ""})
    assert invalid.status_code == 422
    fields = ValidationErrorOut.model_validate(invalid.json()).detail
    assert isinstance(fields, list) and fields[0].loc == ["body", "name"]
    # The service's own 422s name the field in a sentence.
    posted = app_client.post("/v1/kbs/default/points", json={"points": [make_point(0)]})
    type_id = posted.json()["results"][0]["type_id"]
    refused = app_client.get(f"/v1/kbs/default/types/{type_id}/points", params={"cursor": "zz"})
    assert refused.status_code == 422
    assert ValidationErrorOut.model_validate(refused.json()).detail.startswith("cursor:")
    # A body that is not UTF-8 is the declared 400.
    unreadable = app_client.post(
        "/v1/kbs/default/points",
        content=b'{"points": "\xff"}',
        headers={"content-type": "application/json"},
    )
    assert unreadable.status_code == 400 and ErrorOut.model_validate(unreadable.json()).detail


def test_the_csv_route_declares_and_answers_text_csv(spec: dict[str, Any], app_client: Any) -> None:
    ok = spec["paths"]["/v1/kbs/{kb}/types/{type_id}/points.csv"]["get"]["responses"]["200"]
    assert list(ok["content"]) == ["text/csv"]
    posted = app_client.post("/v1/kbs/default/points", json={"points": [make_point(0)]})
    type_id = posted.json()["results"][0]["type_id"]
    answer = app_client.get(f"/v1/kbs/default/types/{type_id}/points.csv")
    assert answer.status_code == 200 and answer.headers["content-type"].startswith("text/csv")


def test_request_models_describe_every_property(spec: dict[str, Any]) -> None:
    schemas = spec["components"]["schemas"]
    for model in REQUEST_MODELS:
        properties = schemas[model.__name__]["properties"]
        undescribed = [name for name, prop in properties.items() if not prop.get("description")]
        assert not undescribed, f"{model.__name__}: {undescribed}"


def test_request_examples_are_valid_requests(spec: dict[str, Any], app_client: Any) -> None:
    schemas = spec["components"]["schemas"]
    for name in EXAMPLED:
        examples = schemas[name].get("examples")
        assert examples, name
        for example in examples:
            model = getattr(models, name, None) or getattr(bindings, name)
            model.model_validate(example)
    # The points example is one a service stores, and the knowledge base one it creates.
    example = schemas["PointsIn"]["examples"][0]
    assert app_client.post("/v1/kbs/default/points", json=example).status_code == 201
    kb = schemas["KnowledgeBaseIn"]["examples"][0]
    assert app_client.post("/v1/kbs", json=kb).status_code == 201

"""With CPKB_SURROGATE__ENABLED=false the service keeps points but has no GP engine."""

from fastapi.testclient import TestClient
from service_support import make_point

from server.app import create_app
from server.settings import Settings


def test_disabled_surrogates_store_points_and_answer_503_to_suggest(sqlite_url: str) -> None:
    app = create_app(Settings(database_url=sqlite_url, surrogate={"enabled": False}))
    with TestClient(app) as http:
        posted = http.post("/v1/kbs/default/points", json={"points": [make_point(0)]})
        assert posted.status_code == 201
        type_id = posted.json()["results"][0]["type_id"]
        answer = http.post(
            f"/v1/kbs/default/types/{type_id}/predict", json={"x": [make_point(0)["x"]]}
        )
        assert answer.status_code == 503
        assert "CPKB_SURROGATE__ENABLED" in answer.json()["detail"]
        assert http.get(f"/v1/kbs/default/types/{type_id}").status_code == 200

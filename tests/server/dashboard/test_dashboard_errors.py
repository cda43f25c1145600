"""HTML pages answer a bad or unknown query parameter with an HTML error page (the API keeps
its JSON), answers are compressed, and /login is styled (issue 56.4)."""

from __future__ import annotations

from typing import Any

import pytest

from tests.service_support import make_graph, make_point


@pytest.fixture
def type_id(core_client: Any) -> str:
    points = [make_point(i, graph=make_graph("Inv-kin", ("box1",))) for i in range(30)]
    response = core_client.post("/v1/kbs/default/points", json={"points": points})
    return response.json()["results"][0]["type_id"]


@pytest.mark.parametrize(
    "params",
    [{"feasible": "maybe"}, {"limit": "0"}, {"colour": "red"}, {"kb": "x" * 100}],
)
def test_html_pages_answer_bad_query_parameters_with_an_html_page(
    core_client: Any, type_id: str, params: dict[str, str]
) -> None:
    for path in ("/", f"/ui/kbs/default/types/{type_id}"):
        if path == "/" and "feasible" in params:
            continue
        page = core_client.get(path, params=params)
        assert page.status_code == 422, (path, params)
        assert page.headers["content-type"].startswith("text/html")
        assert "<h1>Bad request</h1>" in page.text and "Back to the overview" in page.text
        name = next(iter(params))
        assert name in page.text
    # the page's JSON twin keeps answering JSON
    twin = core_client.get(f"/ui/api/kbs/default/types/{type_id}", params={"colour": "red"})
    assert twin.status_code == 422 and twin.headers["content-type"] == "application/json"


def test_an_unknown_type_is_an_html_404_page(core_client: Any) -> None:
    page = core_client.get("/ui/kbs/default/types/0123abcd")
    assert page.status_code == 404 and "<h1>Not found</h1>" in page.text


def test_pages_and_figures_are_compressed(core_client: Any, type_id: str) -> None:
    for path in (
        f"/ui/kbs/default/types/{type_id}",
        f"/ui/kbs/default/types/{type_id}/heatmap.svg",
        "/ui/static/dashboard.css",
    ):
        response = core_client.get(path, headers={"Accept-Encoding": "gzip"})
        assert response.status_code == 200
        assert response.headers.get("content-encoding") == "gzip", path
        raw = int(response.headers["content-length"])
        assert raw < len(response.content)  # httpx decoded a smaller body
    plain = core_client.get("/ui/static/dashboard.css", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers


def test_login_page_is_styled_and_fits_a_phone(core_client: Any) -> None:
    page = core_client.get("/login")
    assert page.status_code == 200
    assert "<style>" in page.text and "prefers-color-scheme:dark" in page.text
    assert "width=device-width" in page.text

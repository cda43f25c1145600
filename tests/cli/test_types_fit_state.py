"""`cpkb types` shows each type's fit state, so a user scripting the protocol by hand sees
when a fit has landed (a real server; the fit is waited for, not timed)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from cli_support import cpkb_in_process
from service_support import make_graph, make_point, run_live_server

from client import CpkbClient


@pytest.mark.slow
def test_types_shows_points_fitted_once_the_fit_has_landed(
    db_url: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    with run_live_server(db_url, tmp_path / "server.log") as server, CpkbClient(server.url) as c:
        c.create_kb("lab")
        c.post_points("lab", [make_point(i, graph=make_graph()) for i in range(12)])
        (summary,) = c.list_types("lab")
        deadline = time.monotonic() + 240  # a bound a loaded machine cannot reach, not a goal
        while time.monotonic() < deadline:
            state = c.get_type("lab", summary.type_id).surrogate
            if state is not None and state.status == "ready" and state.n_fitted == 12:
                break
            time.sleep(0.2)
        else:
            pytest.fail(f"no fit landed: {state}")
        out = cpkb_in_process(capfd, "types", "--kb", "lab", "--url", server.url)
    assert out.returncode == 0, out.stderr
    row = next(line for line in out.stdout.splitlines() if summary.type_id[:8] in line)
    assert "ready" in row and "12/12" in row and "pending" not in row
    assert "fitted" in out.stdout

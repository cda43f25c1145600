"""Tables name every task whole at any terminal width: a suite's shared directory is said once
in the title, `ws00/desk` shows, the name column as wide as its names (issue 56.7)."""

from __future__ import annotations

import pytest
from rich.console import Console

from cpkb.bench.stats import headers
from cpkb.cli.tables import shared_directory, whole_names_table

HEADERS = headers()


def test_the_shared_directory_is_cut_to_workspace_and_task() -> None:
    names = ["my-suite/ws00/desk", "my-suite/ws00/pack", "my-suite/ws01/desk"]
    assert shared_directory(names) == "my-suite/"
    assert shared_directory(["my-suite/ws00/desk"]) == "my-suite/"
    assert shared_directory(["desk", "my-suite/ws00/desk"]) == ""
    assert shared_directory(["a/b/ws00/desk", "a/c/ws00/desk"]) == "a/"
    assert shared_directory([]) == ""


@pytest.mark.parametrize("width", [80, 120])
def test_a_bench_table_of_a_suite_shows_each_workspace_and_task(width: int) -> None:
    tasks = [
        f"/home/someone/suites/my-suite/ws{k:02d}/{t}" for k in range(3) for t in ("desk", "pack")
    ]
    rows = [[task, "cp-bo", "20", *["12.5 ± 3.1"] * (len(HEADERS) - 3)] for task in tasks]
    console = Console(width=width, record=True)
    console.print(whole_names_table(HEADERS, rows, "cpkb bench: 120 runs"))
    text = console.export_text()
    assert "tasks under" in text
    for k in range(3):
        for t in ("desk", "pack"):
            assert f"ws{k:02d}/{t}" in text

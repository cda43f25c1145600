"""The benchmark plots: raster and vector files that open, at print resolution, with the
intervals and the colour of each method, and a by-kind figure for a generated suite."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from cpkb.bench.plots import PALETTE, PNG_DPI, bootstrap_ci, write_plots

SUITE = Path(__file__).resolve().parents[3] / "benchmarks" / "suites" / "dev"


def _records(task: str, method: str, rollouts: list[int]) -> list[dict]:
    return [
        {
            "task": task,
            "method": method,
            "seed": i,
            "rollouts": r,
            "solved": r < 2000,
            "wall_s": r / 50,
            "max_rollouts": 2000,
        }
        for i, r in enumerate(rollouts)
    ]


def _suite_records() -> tuple[list[dict], list[str]]:
    targets = sorted(str(p) for p in SUITE.glob("ws0*/desk.yaml"))[:2]
    assert len(targets) == 2, "the development suite ships several desk targets"
    records = []
    for k, task in enumerate(targets):
        records += _records(task, "quasi-random", [40 + k, 90, 300, 2000, 12])
        records += _records(task, "cp-bo", [5, 9, 14 + k, 30, 700])
    return records, targets


def _check_files(stem: Path) -> None:
    png = Image.open(stem.with_suffix(".png"))
    width, height = png.size
    assert width >= 6 * PNG_DPI and height >= 4 * PNG_DPI
    assert png.info["dpi"][0] == pytest.approx(PNG_DPI, abs=1)
    root = ET.parse(stem.with_suffix(".svg")).getroot()
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    pdf = stem.with_suffix(".pdf").read_bytes()
    assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")


def test_each_plot_is_written_as_png_svg_and_pdf_that_open(tmp_path: Path) -> None:
    records = _records("desk", "quasi-random", [10, 20, 30, 40, 2000]) + _records(
        "desk", "cp-bo", [2, 3, 5, 8, 400]
    )
    paths = write_plots(records, tmp_path, ["desk"], ["quasi-random", "cp-bo"])
    assert sorted(p.name for p in paths) == sorted(
        f"{stem}.{fmt}" for stem in ("rollouts", "wall_time") for fmt in ("png", "svg", "pdf")
    )
    for stem in ("rollouts", "wall_time"):
        _check_files(tmp_path / stem)
    svg = (tmp_path / "rollouts.svg").read_text().lower()
    # Each method keeps its palette colour, boxes and mean diamonds alike.
    assert PALETTE[0].lower() in svg and PALETTE[1].lower() in svg
    assert not (tmp_path / "rollouts_by_kind.png").exists()  # no kind has several tasks


def test_a_suite_whose_targets_share_a_kind_also_gets_a_by_kind_plot(tmp_path: Path) -> None:
    records, _ = _suite_records()
    paths = write_plots(records, tmp_path, methods=["quasi-random", "cp-bo"])
    assert tmp_path / "rollouts_by_kind.svg" in paths
    _check_files(tmp_path / "rollouts_by_kind")


def test_many_tasks_wrap_into_rows_instead_of_one_endless_strip(tmp_path: Path) -> None:
    records = [r for t in range(6) for r in _records(f"task{t}", "quasi-random", [3 + t, 9, 27])]
    write_plots(records, tmp_path)
    width, height = Image.open(tmp_path / "rollouts.png").size
    assert width < 2.5 * height


def test_the_bootstrap_interval_holds_its_statistic_and_needs_two_values() -> None:
    values = [1.0, 2.0, 3.0, 50.0, 400.0]
    low, high = bootstrap_ci(values, lambda a: a.mean(axis=1))
    assert low < np.mean(values) < high
    assert min(values) <= low and high <= max(values)
    low, high = bootstrap_ci(values, lambda a: np.median(a, axis=1))
    assert low <= np.median(values) <= high
    assert bootstrap_ci([7.0], lambda a: a.mean(axis=1)) is None
    assert bootstrap_ci(values, lambda a: a.mean(axis=1)) == bootstrap_ci(
        values, lambda a: a.mean(axis=1)
    )

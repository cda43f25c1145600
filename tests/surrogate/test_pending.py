"""The in-process pending book: which points answer a suggestion."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.pending import SAME_ATOL, PendingBook, _same

BIND = {"#pose": "p", "#dir": "d"}


def test_a_point_at_the_suggested_values_answers_it_and_one_elsewhere_does_not() -> None:
    book = PendingBook(ttl_s=30.0)
    book.add("kb", {"p": [0.1, 0.2, 0.0], "d": "top"}, [("T1", BIND)])
    assert book.answered("kb", "T1", [{"#pose": [0.1, 0.2, 1e-3], "#dir": "top"}]) == 0
    assert book.answered("kb", "T1", [{"#pose": [0.1, 0.2, 0.0], "#dir": "front"}]) == 0
    assert book.answered("kb", "T2", [{"#pose": [0.1, 0.2, 0.0], "#dir": "top"}]) == 0
    assert book.count("kb") == 1
    within = [0.1 + SAME_ATOL / 2, 0.2, 0.0]
    assert book.answered("kb", "T1", [{"#pose": within, "#dir": "top"}]) == 1
    assert book.count("kb") == 0


@pytest.mark.parametrize(
    ("a", "b"),
    [
        (0.5, 0.5),
        (0.5, 0.5 + 2 * SAME_ATOL),
        ([0.1, 0.2], (0.1, 0.2)),
        ([0.1, 0.2], [0.1, 0.2, 0.3]),
        ([0.1, float("nan")], [0.1, float("nan")]),
        ([float("inf"), 1], [float("inf"), 1.0]),
        ([0.5, 0.5], 0.5),
        ([[0.1, 0.2]], [[0.1, 0.2]]),
        ([0.1, 0.2], ["0.1", 0.2]),
        ("top", "top"),
        ("top", [0.1]),
        ([0.9, 0.2], [0.1, 0.2]),
        ([1, "x"], [2, "x"]),
        ([0.1], [0.1, 0.1]),
        ([0.2], [0.1, 0.2]),
        ([[0.1, 0.2]], [[0.9, 0.2]]),
    ],
)
def test_same_agrees_with_numpy_allclose(a: object, b: object) -> None:
    try:
        expected = bool(
            np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=0, atol=SAME_ATOL)
        )
    except (TypeError, ValueError):
        expected = False
    if isinstance(a, str) or isinstance(b, str):
        expected = a == b
    assert _same(a, b) == expected


def test_same_agrees_with_numpy_allclose_on_random_poses() -> None:
    rng = np.random.default_rng(0)
    for _ in range(500):
        a = rng.random(3)
        b = a + rng.choice([0.0, 0.3, 2.0]) * SAME_ATOL * rng.standard_normal(3)
        expected = bool(np.allclose(a, b, rtol=0, atol=SAME_ATOL))
        assert _same(a.tolist(), b.tolist()) == expected

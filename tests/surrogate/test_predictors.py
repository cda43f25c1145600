"""The counted stated prior centred per categorical choice (`PriorPredictor.by_choice`)."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder
from surrogate.predictors import PriorPredictor

GRASP_AND_PLACE = {
    "#dir": {"kind": "categorical", "choices": ["top", "front", "left"]},
    "#pose": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
}


def _encoder(space: dict) -> SpaceEncoder:
    return SpaceEncoder(space_from_json(space))


def _points(encoder: SpaceEncoder, grasp: str, poses: np.ndarray) -> np.ndarray:
    return encoder.encode_points([{"#dir": grasp, "#pose": list(map(float, p))} for p in poses])


def _shelf_prior(encoder: SpaceEncoder) -> PriorPredictor:
    """Twenty failures of the top grasp, all in one corner of the placement square."""
    poses = np.random.default_rng(3).random((20, 2)) * 0.2
    none = np.zeros((0, encoder.dim))
    return PriorPredictor(none, _points(encoder, "top", poses)).counted(2.0)


def test_a_choice_that_failed_everywhere_is_rated_low_far_from_its_failures_too() -> None:
    """Counted alone, a place far from the top grasp's failures is rated at the centre; by
    choice, the top grasp's rate (1 / 22 with s = 2) over the best choice's (an untried grasp,
    the centre) sets its centre, while an untried grasp keeps the centre."""
    encoder = _encoder(GRASP_AND_PLACE)
    counted = _shelf_prior(encoder)
    by_choice = counted.by_choice(encoder.choice_rows())
    far_top = _points(encoder, "top", np.array([[0.9, 0.9]]))
    far_front = _points(encoder, "front", np.array([[0.9, 0.9]]))
    assert counted.proba(far_top)[0] > 0.45
    assert by_choice.proba(far_top)[0] < 1 / 22 + 1e-9
    assert by_choice.proba(far_front)[0] == pytest.approx(counted.proba(far_front)[0])
    near_top = _points(encoder, "top", np.array([[0.1, 0.1]]))
    assert by_choice.proba(near_top)[0] < counted.proba(near_top)[0]


def test_the_best_choice_keeps_the_centre_once_every_choice_has_failed() -> None:
    """Relative to the best rate: with every grasp tried and failed, the one that failed least
    is rated as the counted prior rates it, the others lower by their rates' ratio."""
    encoder = _encoder(GRASP_AND_PLACE)
    corner = np.zeros((1, 2))
    failures = np.vstack(
        [
            _points(encoder, "top", np.repeat(corner, 8, axis=0)),
            _points(encoder, "front", np.repeat(corner, 2, axis=0)),
            _points(encoder, "left", np.repeat(corner, 2, axis=0)),
        ]
    )
    counted = PriorPredictor(np.zeros((0, encoder.dim)), failures).counted(2.0)
    by_choice = counted.by_choice(encoder.choice_rows())
    far_front = _points(encoder, "front", np.array([[1.0, 1.0]]))
    far_top = _points(encoder, "top", np.array([[1.0, 1.0]]))
    assert by_choice.proba(far_front)[0] == pytest.approx(counted.proba(far_front)[0])
    rate_top, rate_front = 1 / 10, 1 / 4  # (s c + 0) / (s + n), s = 2, c = 0.5
    expected = (2 * 0.5 * rate_top / rate_front) / (2 + _infeasible_mass(counted, far_top))
    assert by_choice.proba(far_top)[0] == pytest.approx(expected, rel=1e-6)


def _infeasible_mass(prior: PriorPredictor, z: np.ndarray) -> float:
    """B(x) of the counted prior, read back from its answer with the centre at 0.5."""
    p = prior.proba(z)[0]
    return float(prior.strength * prior.center / p - prior.strength)


def test_choices_that_encode_alike_are_one_choice() -> None:
    """A symmetric embedding (front and back of a box place alike) gives one row for both:
    back's failures count against front, and the possible choices are the distinct rows."""
    space = {
        "#dir": {
            "kind": "categorical",
            "choices": ["top", "front", "back"],
            "embedding": {"top": [0.0, 1.0], "front": [1.0, 0.0], "back": [1.0, 0.0]},
        },
        "#pose": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]},
    }
    encoder = _encoder(space)
    ((_, rows),) = encoder.choice_rows()
    assert len(rows) == 2
    poses = np.zeros((6, 2))
    counted = PriorPredictor(np.zeros((0, encoder.dim)), _points(encoder, "back", poses))
    by_choice = counted.counted(2.0).by_choice(encoder.choice_rows())
    far_front = _points(encoder, "front", np.array([[1.0, 1.0]]))
    far_top = _points(encoder, "top", np.array([[1.0, 1.0]]))
    assert by_choice.proba(far_front)[0] < 1 / 8 + 1e-9 < by_choice.proba(far_top)[0]


def test_without_points_or_counting_the_choices_change_nothing() -> None:
    encoder = _encoder(GRASP_AND_PLACE)
    none = np.zeros((0, encoder.dim))
    z = _points(encoder, "top", np.random.default_rng(0).random((5, 2)))
    empty = PriorPredictor(none, none).counted(2.0).by_choice(encoder.choice_rows())
    assert np.allclose(empty.proba(z), 0.5)
    nearest = PriorPredictor(none, _shelf_prior(encoder).infeasible)
    assert np.allclose(nearest.by_choice(encoder.choice_rows()).proba(z), nearest.proba(z))


def test_a_type_of_choices_alone_is_counted_once() -> None:
    """With no input but the grasp, the counted prior already rates each grasp by its own
    points: the centre stays, so a grasp that failed five times is rated 1/7, not lower."""
    encoder = _encoder({"#dir": GRASP_AND_PLACE["#dir"]})
    top = encoder.encode_points([{"#dir": "top"}])
    failures = np.repeat(top, 5, axis=0)
    counted = PriorPredictor(np.zeros((0, encoder.dim)), failures).counted(2.0)
    by_choice = counted.by_choice(encoder.choice_rows())
    assert by_choice.proba(top)[0] == pytest.approx(counted.proba(top)[0])
    assert by_choice.proba(top)[0] == pytest.approx(1 / 7, abs=1e-6)

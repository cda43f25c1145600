"""The points a suggestion keeps away from: a set and the points a batch adds to it."""

from __future__ import annotations

import numpy as np

from surrogate.avoid import AvoidSet
from surrogate.domains import CategoricalDomain, ContinuousDomain, continuous
from surrogate.encoding import SpaceEncoder

SPACE = {
    "dir": CategoricalDomain(choices=["front", "top", "left"]),
    "pose": ContinuousDomain(low=[0.0, 0.0], high=[2.0, 1.0]),
}
EXCLUDE = [{"dir": "top", "pose": [1.0, 0.5]}, {"pose": [0.2, 0.9]}]
PENDING = [{"dir": "left", "pose": [1.5, 0.1]}]
MORE = [{"dir": "front", "pose": [0.4, 0.4]}, {"dir": "top"}]


def candidates() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    points = [{"dir": "top", "pose": [1.0, 0.5]}, {"dir": "front", "pose": [0.4, 0.4]}]
    points += [
        {"dir": ["front", "top", "left"][rng.integers(3)], "pose": [2 * rng.random(), rng.random()]}
        for _ in range(40)
    ]
    return SpaceEncoder(SPACE).columns(points)


def test_a_set_and_its_added_points_together_equal_a_set_built_with_them() -> None:
    """A batch's picks join its excluded points through `only`: or-ed verdicts and the minimum
    distance of the two parts are those of one set built with every point."""
    base = AvoidSet(SPACE, {}, EXCLUDE, PENDING)
    more = base.only(MORE)
    built = AvoidSet(SPACE, {}, EXCLUDE + MORE, PENDING)
    cols = candidates()
    z = base.encoder.encode(cols)
    np.testing.assert_array_equal(base.excluded(cols) | more.excluded(cols), built.excluded(cols))
    both = np.minimum(base.nearest(z), more.nearest(z))
    np.testing.assert_allclose(both, built.nearest(z), atol=1e-7)
    np.testing.assert_array_equal(more.pending_distances(z), np.zeros((len(z), 0)))
    assert more.excluded(cols)[1] and not base.excluded(cols)[1]
    assert built.excluded(cols)[:2].all()


def test_no_point_to_avoid_is_no_spread() -> None:
    avoid = AvoidSet(SPACE, {}, [], [])
    z = avoid.encoder.encode(candidates())
    assert np.isinf(avoid.nearest(z)).all()
    np.testing.assert_array_equal(avoid.spread(z), np.zeros(len(z)))


def test_invalid_pending_points_are_left_out_and_the_rest_kept() -> None:
    """Pending points come from other requests: one without a free variable, or with a value
    outside the space, is left out; the valid ones of its group still repel."""
    bad = [
        {"dir": "left", "pose": [5.0, 0.1]},  # outside the pose's range
        {"dir": "up", "pose": [0.5, 0.5]},  # not a choice
        {"other": 1},  # no free variable
    ]
    avoid = AvoidSet(SPACE, {}, EXCLUDE, [*bad, *PENDING, {"pose": [0.3, 0.3]}])
    kept = sorted(len(g.z) for g in avoid.pending_groups)
    assert kept == [1, 1]  # PENDING's point, and the pose-only one
    clean = AvoidSet(SPACE, {}, EXCLUDE, [*PENDING, {"pose": [0.3, 0.3]}])
    z = avoid.encoder.encode(candidates())
    np.testing.assert_allclose(avoid.pending_distances(z), clean.pending_distances(z))


def test_a_periodic_heading_has_no_walls_and_is_near_across_its_seam() -> None:
    """A candidate just across the seam from a point to avoid is near it, and nothing caps its
    distance at the heading's ends: a heading has no walls."""
    pose = continuous([0.0, 0.0, -np.pi], [1.0, 1.0, np.pi], "shelf", 2, None, False, True)
    avoid = AvoidSet({"p": pose}, {}, [{"p": [0.5, 0.5, np.pi - 0.05]}], [])
    z = avoid.encoder.encode(avoid.encoder.columns([{"p": [0.5, 0.5, -np.pi + 0.05]}]))
    assert avoid.nearest(z)[0] < 0.02
    far = AvoidSet({"p": pose}, {}, [{"p": [0.5, 0.5, 0.0]}], [])
    z = far.encoder.encode(far.encoder.columns([{"p": [0.5, 0.5, -np.pi + 0.01]}]))
    plain = AvoidSet({"p": continuous([0.0, 0.0, -np.pi], [1.0, 1.0, np.pi])}, {}, [], [])
    assert far.nearest(z)[0] > 0.1
    assert plain.encoder.dim == 3 and far.encoder.dim == 4

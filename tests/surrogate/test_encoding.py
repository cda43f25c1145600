"""Decision spaces -> GP inputs and back."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from surrogate.domains import (
    CategoricalDomain,
    ContinuousDomain,
    categorical,
    continuous,
    domain_from_json,
    domain_to_json,
)
from surrogate.encoding import (
    EncodingError,
    SpaceEncoder,
    encoder_for,
    metric_reach,
    same_domain,
)

DIRS = ["front", "right", "top", "back", "left"]
APPROACH = {
    "front": [1.0, 0.0, 0.0],
    "right": [0.0, -1.0, 0.0],
    "top": [0.0, 0.0, 1.0],
    "back": [-1.0, 0.0, 0.0],
    "left": [0.0, 1.0, 0.0],
}


def space(embedding: bool) -> dict:
    return {
        "dir": CategoricalDomain(choices=DIRS, embedding=APPROACH if embedding else None),
        "pose": ContinuousDomain(low=[-1.0, 0.0, -3.0], high=[1.0, 2.0, 3.0]),
    }


@pytest.mark.parametrize("embedding", [False, True])
def test_points_round_trip_through_gp_inputs(embedding: bool) -> None:
    encoder = SpaceEncoder(space(embedding))
    rng = np.random.default_rng(0)
    points = [
        {"dir": DIRS[i % 5], "pose": [rng.uniform(-1, 1), rng.uniform(0, 2), rng.uniform(-3, 3)]}
        for i in range(20)
    ]
    z = encoder.encode(encoder.columns(points))
    assert z.shape == (20, encoder.dim) and z.min() >= 0.0 and z.max() <= 1.0
    back = encoder.points(encoder.decode(z))
    for original, decoded in zip(points, back, strict=True):
        assert decoded["dir"] == original["dir"]
        assert np.allclose(decoded["pose"], original["pose"])


def test_one_hot_keeps_every_pair_of_choices_equally_far() -> None:
    encoder = SpaceEncoder({"dir": CategoricalDomain(choices=DIRS)})
    z = encoder.encode({"dir": np.arange(5)})
    d = np.linalg.norm(z[:, None] - z[None], axis=-1)
    off_diagonal = d[~np.eye(5, dtype=bool)]
    assert encoder.dim == 5 and np.allclose(off_diagonal, off_diagonal[0])


def test_embedding_carries_geometry_not_codes() -> None:
    encoder = SpaceEncoder({"dir": CategoricalDomain(choices=DIRS, embedding=APPROACH)})
    z = encoder.encode({"dir": np.arange(5)})
    dist = lambda a, b: np.linalg.norm(z[DIRS.index(a)] - z[DIRS.index(b)])  # noqa: E731
    assert encoder.dim == 3
    assert dist("front", "back") > dist("front", "right")
    assert np.isclose(dist("front", "right"), dist("front", "left"))


def test_bad_values_name_their_field() -> None:
    encoder = SpaceEncoder(space(False))
    with pytest.raises(EncodingError, match=r"x\[1\]\.dir"):
        encoder.columns([{"dir": "top", "pose": [0, 1, 0]}, {"dir": "up", "pose": [0, 1, 0]}], "x")
    with pytest.raises(EncodingError, match="pose"):
        encoder.columns([{"dir": "top", "pose": [5.0, 1.0, 0.0]}])
    with pytest.raises(EncodingError, match="pose"):
        encoder.columns([{"dir": "top", "pose": [0.0, 1.0]}])
    with pytest.raises(EncodingError, match="missing"):
        encoder.columns([{"dir": "top"}])


def test_same_domain_compares_values_not_embeddings() -> None:
    assert same_domain(space(True)["dir"], space(False)["dir"])
    assert not same_domain(space(True)["dir"], CategoricalDomain(choices=DIRS[:4]))
    assert not same_domain(space(True)["pose"], ContinuousDomain(low=[0, 0, 0], high=[1, 1, 1]))
    assert not same_domain(space(True)["pose"], space(True)["dir"])


def test_same_domain_tolerates_rounding_of_bounds() -> None:
    box = ContinuousDomain(low=(0.0, 0.1), high=(1.0, 0.3))
    assert same_domain(box, ContinuousDomain(low=[0.0, 0.1], high=[1.0, 0.3]))
    assert same_domain(box, ContinuousDomain(low=(0.0, 0.1), high=(1.0, 0.1 + 0.2)))
    assert not same_domain(box, ContinuousDomain(low=(0.0, 0.1), high=(1.0, 0.31)))


def framed_space(second_frame: str | None) -> dict:
    return {
        "a": ContinuousDomain(low=[0.0, 0.0], high=[1.0, 2.0], frame="tray"),
        "dir": CategoricalDomain(choices=DIRS),
        "b": ContinuousDomain(low=[0.0, 0.0], high=[1.0, 2.0], frame=second_frame),
    }


def test_two_places_in_one_frame_add_their_separation() -> None:
    encoder = SpaceEncoder(framed_space("tray"))
    points = [
        {"a": [0.2, 1.0], "dir": "top", "b": [0.5, 0.2]},
        {"a": [1.0, 0.0], "dir": "top", "b": [0.0, 2.0]},
    ]
    z = encoder.encode(encoder.columns(points))
    assert encoder.dim == 2 + 5 + 2 + 2
    np.testing.assert_allclose(z[:, -2:], [[0.3, 0.4], [1.0, 1.0]])
    back = encoder.points(encoder.decode(z))
    np.testing.assert_allclose(back[1]["b"], [0.0, 2.0])
    assert back[0]["dir"] == "top"


@pytest.mark.parametrize("second_frame", [None, "shelf"])
def test_places_in_different_frames_add_nothing(second_frame: str | None) -> None:
    assert SpaceEncoder(framed_space(second_frame)).dim == 9


def test_search_distances_leave_separations_out() -> None:
    assert SpaceEncoder(framed_space("tray"), separations=False).dim == 9


def planar_space() -> dict:
    pose = ContinuousDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0], frame="tray", heading=2)
    return {"a": pose, "b": pose}


def relative_pose(a: list[float], b: list[float]) -> np.ndarray:
    encoder = SpaceEncoder(planar_space())
    return encoder.encode(encoder.columns([{"a": a, "b": b}]))[0, encoder.base_dim :]


def test_two_planar_poses_in_one_frame_add_their_relative_pose() -> None:
    assert SpaceEncoder(planar_space()).dim == 3 + 3 + 5
    # b's hand heads along +x (heading seed 0.5 is angle 0): a lies 0.2 ahead of it ...
    ahead = relative_pose([0.7, 0.5, 0.75], [0.5, 0.5, 0.5])
    np.testing.assert_allclose(ahead[:2], [0.1, 0.0], atol=1e-12)
    # ... and b lies 0.2 across a's hand, which heads along +y (seed 0.75: angle pi / 2)
    np.testing.assert_allclose(ahead[2:4], [0.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(ahead[4], 0.5)  # a quarter turn apart
    # turned half a turn, b's hand sees a on the same line: the offset's sign drops out
    np.testing.assert_allclose(
        relative_pose([0.7, 0.5, 0.75], [0.5, 0.5, 0.0])[:2], [0.1, 0.0], atol=1e-12
    )


def test_framed_pairs_without_a_heading_keep_their_separation_at_any_width() -> None:
    place = ContinuousDomain(low=[0.0] * 5, high=[1.0] * 5, frame="tray")
    encoder = SpaceEncoder({"a": place, "b": place})
    z = encoder.encode(encoder.columns([{"a": [0.1] * 5, "b": [0.4] * 5}]))
    assert encoder.dim == 15
    np.testing.assert_allclose(z[0, 10:], [0.3] * 5)


def test_relative_pose_does_not_change_when_the_whole_scene_turns() -> None:
    """A quarter turn about the frame's centre moves both poses and both headings alike."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = rng.uniform(0.1, 0.9, size=(2, 3))

        def turned(p: np.ndarray) -> list[float]:
            return [1.0 - p[1], p[0], (p[2] + 0.25) % 1.0]

        np.testing.assert_allclose(
            relative_pose(list(a), list(b)), relative_pose(turned(a), turned(b)), atol=1e-9
        )


def test_the_heading_difference_wraps_around_the_turn() -> None:
    assert relative_pose([0.5, 0.5, 0.95], [0.5, 0.5, 0.05])[4] == pytest.approx(0.2)


def test_the_wire_contract_refuses_a_heading_without_a_framed_planar_pose() -> None:
    """The wire models check domains; the surrogate library trusts what they let through."""
    from contract.models import ContinuousDomain as WireDomain

    with pytest.raises(ValidationError, match="heading needs a frame"):
        WireDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0], heading=2)
    with pytest.raises(ValidationError, match="heading needs a frame"):
        WireDomain(low=[0.0, 0.0], high=[1.0, 1.0], frame="tray", heading=1)


def metric_space(scale_a: tuple[float, float], scale_b: tuple[float, float]) -> dict:
    def pose(scale: tuple[float, float]) -> ContinuousDomain:
        return continuous([0.0] * 3, [1.0] * 3, frame="tray", heading=2, scale=scale)

    return {"a": pose(scale_a), "b": pose(scale_b)}


def seed_at(metres: tuple[float, float], scale: tuple[float, float], heading: float) -> list:
    """The seed of a place `metres` from the frame's centre, its hand heading at `heading`."""
    return [0.5 + metres[0] / (2 * scale[0]), 0.5 + metres[1] / (2 * scale[1]), heading]


def metric_offsets(space: dict, a: list[float], b: list[float]) -> np.ndarray:
    """a's offset `(|u|, |v|)` in b's heading frame, in metres, from the encoded features."""
    encoder = SpaceEncoder(space)
    features = encoder.encode(encoder.columns([{"a": a, "b": b}]))[0, encoder.base_dim :]
    reach = metric_reach((space["a"].scale, space["b"].scale))
    return features[:2] * 2 * reach


# A 0.60 x 0.20 m region with bodies of 0.04 and 0.08 m footprints, and a 1.0 x 0.4 m one with
# bodies of 0.10 and 0.06 m: the seed's units are other lengths in x and y, and per body.
SCALES = [((0.28, 0.08), (0.26, 0.06)), ((0.45, 0.15), (0.47, 0.17))]


@pytest.mark.parametrize(("scale_a", "scale_b"), SCALES)
def test_a_metric_relative_pose_is_the_offset_in_metres(scale_a, scale_b) -> None:
    space = metric_space(scale_a, scale_b)
    a_at, b_at = (0.10, 0.03), (-0.05, -0.01)  # 0.15 m along x, 0.04 m along y apart
    # b's hand heads along +x (seed 0.5): the offset is along x and across it along y ...
    along = metric_offsets(space, seed_at(a_at, scale_a, 0.3), seed_at(b_at, scale_b, 0.5))
    np.testing.assert_allclose(along, [0.15, 0.04], atol=1e-12)
    # ... and along +y (seed 0.75) the other way round
    across = metric_offsets(space, seed_at(a_at, scale_a, 0.3), seed_at(b_at, scale_b, 0.75))
    np.testing.assert_allclose(across, [0.04, 0.15], atol=1e-12)


def test_seed_units_would_not_give_the_metric_offset() -> None:
    """Without scales, the same metric places encode unlike each other (the test above can fail)."""
    (a_scale, b_scale), _ = SCALES
    a, b = seed_at((0.10, 0.03), a_scale, 0.3), seed_at((-0.05, -0.01), b_scale, 0.5)
    unscaled = relative_pose(a, b)[:2]
    assert not np.allclose(unscaled / unscaled[0], [1.0, 0.04 / 0.15], atol=0.05)


def test_a_square_frame_with_equal_bodies_encodes_as_seed_units_do() -> None:
    """Metric frames change nothing where seed units were already metric up to one factor."""
    space = metric_space((0.2, 0.2), (0.2, 0.2))
    encoder = SpaceEncoder(space)
    a, b = [0.7, 0.2, 0.75], [0.4, 0.6, 0.1]
    metric = encoder.encode(encoder.columns([{"a": a, "b": b}]))[0, encoder.base_dim :]
    np.testing.assert_allclose(metric, relative_pose(a, b), atol=1e-12)


def test_a_pair_with_one_scale_only_keeps_the_seed_unit_encoding() -> None:
    space = {**metric_space((0.28, 0.08), (0.26, 0.06)), "b": planar_space()["b"]}
    encoder = SpaceEncoder(space)
    a, b = [0.7, 0.2, 0.75], [0.4, 0.6, 0.1]
    mixed = encoder.encode(encoder.columns([{"a": a, "b": b}]))[0, encoder.base_dim :]
    np.testing.assert_allclose(mixed, relative_pose(a, b), atol=1e-12)


def test_a_scale_survives_the_wire_and_needs_a_framed_planar_pose() -> None:
    from contract.models import ContinuousDomain as WireDomain

    wire = WireDomain(low=[0.0] * 3, high=[1.0] * 3, frame="tray", heading=2, scale=[0.3, 0.1])
    domain = domain_from_json(wire.model_dump())
    assert domain.scale == (0.3, 0.1)
    assert WireDomain.model_validate(domain_to_json(domain)) == wire
    old = domain_from_json(WireDomain(low=[0.0] * 3, high=[1.0] * 3).model_dump())
    assert old.scale is None and "scale" not in domain_to_json(old)
    with pytest.raises(ValidationError, match="scale needs a heading"):
        WireDomain(low=[0.0, 0.0], high=[1.0, 1.0], frame="tray", scale=[0.3, 0.1])
    with pytest.raises(ValidationError, match="half extents"):
        WireDomain(low=[0.0] * 3, high=[1.0] * 3, frame="tray", heading=2, scale=[0.3, -0.1])


def relative_only_space() -> dict:
    pose = continuous([0.0, 0.0, -np.pi], [1.0, 1.0, np.pi], "tray", 2, None, True)
    return {"dir": CategoricalDomain(choices=DIRS), "a": pose, "b": pose}


def test_a_relative_only_pair_is_seen_through_its_relative_pose_alone() -> None:
    """Two placements marked relative-only add no columns of their own: a pair moved together
    across the tray encodes alike, the grasp keeps its columns, and a type with one such pose
    (nothing to be relative to) keeps that pose's columns."""
    encoder = SpaceEncoder(relative_only_space())
    assert encoder.dim == len(DIRS) + 5 and encoder.base_dim == len(DIRS)
    z = encoder.encode_points(
        [
            {"dir": "top", "a": [0.2, 0.3, 0.4], "b": [0.5, 0.3, 0.4]},
            {"dir": "top", "a": [0.6, 0.7, 0.4], "b": [0.9, 0.7, 0.4]},
            {"dir": "top", "a": [0.6, 0.7, 0.4], "b": [0.9, 0.1, 0.4]},
        ]
    )
    np.testing.assert_allclose(z[0], z[1], atol=1e-12)
    assert np.abs(z[0] - z[2]).max() > 0.1
    full = SpaceEncoder({**relative_only_space(), "a": planar_space()["a"]})
    assert full.dim == len(DIRS) + 3 + 5  # `b` alone is relative-only: `a` keeps its columns
    alone = SpaceEncoder({"a": relative_only_space()["a"]})
    assert alone.dim == 3
    with pytest.raises(ValueError, match="relative-only"):
        encoder.decode(z)


@pytest.mark.parametrize("flag", ["relative_only", "periodic"])
def test_a_pose_flag_survives_the_wire_needs_a_heading_and_off_leaves_the_contract(flag) -> None:
    from contract.models import ContinuousDomain as WireDomain

    pose = {"low": [0.0] * 3, "high": [1.0] * 3, "frame": "tray"}
    wire = WireDomain(**pose, heading=2, **{flag: True})
    domain = domain_from_json(wire.model_dump())
    assert getattr(domain, flag)
    assert WireDomain.model_validate(domain_to_json(domain)) == wire
    off = WireDomain(**pose, heading=2, **{flag: False})
    assert flag not in off.model_dump(exclude_none=True)  # type ids stay as they were
    assert not getattr(domain_from_json(off.model_dump()), flag)
    with pytest.raises(ValidationError, match=f"{flag} needs a heading"):
        WireDomain(**pose, **{flag: True})


def periodic_pose(periodic: bool = True) -> ContinuousDomain:
    return continuous([0.0, 0.0, -np.pi], [1.0, 1.0, np.pi], "shelf", 2, None, False, periodic)


def test_a_periodic_heading_is_near_across_the_seam_and_as_near_as_before_elsewhere() -> None:
    """The two ends of the heading range are one heading: on a circle they encode a small turn
    apart, where the plain column puts them furthest apart; away from the seam a small turn
    moves about as far as in the plain column."""
    circle = SpaceEncoder({"p": periodic_pose()})
    plain = SpaceEncoder({"p": periodic_pose(periodic=False)})
    assert circle.dim == 4 and plain.dim == 3
    seam = [{"p": [0.3, 0.6, -np.pi + 0.05]}, {"p": [0.3, 0.6, np.pi - 0.05]}]
    inside = [{"p": [0.3, 0.6, 0.4]}, {"p": [0.3, 0.6, 0.5]}]

    def apart(encoder: SpaceEncoder, points: list[dict]) -> float:
        z = encoder.encode_points(points)
        assert z.min() >= 0.0 and z.max() <= 1.0
        return float(np.linalg.norm(z[0] - z[1]))

    assert apart(circle, seam) == pytest.approx(0.1 / (2 * np.pi), rel=1e-3)
    assert apart(plain, seam) > 0.95
    assert apart(circle, inside) == pytest.approx(apart(plain, inside), rel=1e-3)


def test_a_periodic_heading_decodes_back_to_its_value() -> None:
    encoder = SpaceEncoder({"dir": CategoricalDomain(choices=DIRS), "p": periodic_pose()})
    rng = np.random.default_rng(3)
    points = [
        {"dir": DIRS[i % 5], "p": [rng.random(), rng.random(), rng.uniform(-np.pi, np.pi)]}
        for i in range(30)
    ]
    back = encoder.points(encoder.decode(encoder.encode_points(points)))
    for original, decoded in zip(points, back, strict=True):
        assert decoded["dir"] == original["dir"]
        np.testing.assert_allclose(decoded["p"], original["p"], atol=1e-9)


def test_the_surrogate_refuses_a_periodic_pose_without_a_heading() -> None:
    with pytest.raises(ValueError, match="periodic needs a heading"):
        continuous([0.0] * 3, [1.0] * 3, "shelf", None, None, False, True)


def test_a_shared_encoder_serves_every_copy_of_a_space_and_encodes_as_a_new_one() -> None:
    """`encoder_for`: one encoder per distinct space (an embedding or a frame makes another),
    giving exactly what an encoder built afresh gives."""
    space = {
        "g": categorical(["top", "side"], {"top": [0, 0, 1], "side": [1, 0, 0]}),
        "a": continuous([0, 0, 0], [1, 1, 1], frame="tray", heading=2),
        "b": continuous([0, 0, 0], [1, 1, 1], frame="tray", heading=2),
    }
    shared = encoder_for(space)
    assert encoder_for(dict(space)) is shared
    assert encoder_for(space, separations=False) is not shared
    other = {**space, "g": categorical(["top", "side"], {"top": [0, 0, 1], "side": [0, 1, 0]})}
    assert encoder_for(other) is not shared
    points = [
        {"g": "side", "a": [0.2, 0.3, 0.9], "b": [0.7, 0.1, 0.05]},
        {"g": "top", "a": [0.0, 1.0, 0.5], "b": [0.5, 0.5, 0.5]},
    ]
    np.testing.assert_array_equal(
        shared.encode_points(points), SpaceEncoder(space).encode_points(points)
    )

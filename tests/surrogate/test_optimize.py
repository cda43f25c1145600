"""MPF and UCB maximised over mixed spaces: intersections, fixed variables, exclude, seeds."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.acquisition import MPF, ConstraintTerm, PendingPoints, Scored, ucb
from surrogate.config import OptimizerConfig
from surrogate.domains import CategoricalDomain, ContinuousDomain
from surrogate.encoding import SpaceEncoder
from surrogate.models import fit_classifier, fit_regression
from surrogate.optimize import (
    SpaceExhausted,
    maximize,
    maximize_batch,
    space_filling,
)
from surrogate.predictors import PriorPredictor

DIRS = ["front", "right", "top", "back", "left"]
SPACE = {
    "dir": CategoricalDomain(choices=DIRS),
    "pose": ContinuousDomain(low=[0.0, 0.0], high=[1.0, 1.0]),
}
BIND = {"dir": "dir", "pose": "pose"}


def right_half(c: dict) -> np.ndarray:
    return c["pose"][:, 0] > 0.6


def low_band_not_top(c: dict) -> np.ndarray:
    return (c["pose"][:, 1] < 0.35) & (c["dir"] != DIRS.index("top"))


@pytest.fixture(scope="module")
def mpf() -> MPF:
    encoder = SpaceEncoder(SPACE)
    rng = np.random.default_rng(0)
    points = [{"dir": DIRS[rng.integers(5)], "pose": rng.random(2).tolist()} for _ in range(80)]
    cols = encoder.columns(points)
    z = encoder.encode(cols)
    terms = [
        ConstraintTerm.build(
            name, fit_classifier(z, truth(cols), seed=0, max_iters=100).predictor, SPACE, BIND, {}
        )
        for name, truth in (("a", right_half), ("b", low_band_not_top))
    ]
    return MPF(terms)


def truly_feasible(x: dict) -> bool:
    cols = SpaceEncoder(SPACE).columns([x])
    return bool(right_half(cols)[0] and low_band_not_top(cols)[0])


@pytest.mark.slow
def test_mpf_lands_in_the_intersection_of_two_constraints(mpf: MPF) -> None:
    found = [maximize(mpf, SPACE, seed=seed) for seed in range(5)]
    assert all(truly_feasible(s.x) for s in found)
    assert all(s.value > 0.5 for s in found)


def test_seed_reproduces_and_different_seeds_explore(mpf: MPF) -> None:
    assert maximize(mpf, SPACE, seed=11) == maximize(mpf, SPACE, seed=11)
    xs = {str(maximize(mpf, SPACE, seed=s).x) for s in range(4)}
    assert len(xs) > 1


def test_fixed_variables_are_respected(mpf: MPF) -> None:
    top = maximize(mpf, SPACE, fixed={"dir": "top"}, seed=0)
    assert top.x["dir"] == "top" and top.value < 0.5  # top breaks constraint b everywhere
    pose = maximize(mpf, SPACE, fixed={"pose": [0.9, 0.1]}, seed=0)
    assert pose.x["pose"] == [0.9, 0.1] and pose.x["dir"] != "top"


def test_excluded_points_are_never_proposed(mpf: MPF) -> None:
    first = maximize(mpf, SPACE, seed=3)
    second = maximize(mpf, SPACE, exclude=[first.x], seed=3)
    assert second.x != first.x
    cat = {"dir": SPACE["dir"]}
    only_dir = MPF(
        [ConstraintTerm.build("c", mpf.terms[1].predictor, SPACE, BIND, {"pose": [0.9, 0.1]})]
    )
    left = maximize(only_dir, cat, exclude=[{"dir": d} for d in DIRS if d != "top"], seed=0)
    assert left.x == {"dir": "top"}
    with pytest.raises(SpaceExhausted):
        maximize(only_dir, cat, exclude=[{"dir": d} for d in DIRS], seed=0)


def test_pending_points_push_suggestions_apart(mpf: MPF) -> None:
    first = maximize(mpf, SPACE, seed=5)
    with_pending = MPF(mpf.terms, pending=PendingPoints([first.x]))
    second = maximize(with_pending, SPACE, seed=5)
    gap = np.linalg.norm(np.subtract(first.x["pose"], second.x["pose"]))
    assert second.x["dir"] != first.x["dir"] or gap > 0.1
    assert truly_feasible(second.x)


def test_margin_spreads_children_over_the_likely_feasible_region(mpf: MPF) -> None:
    """Children of one node: the margin rule keeps them feasible but apart, where the plain
    argmax piles them up next to each other."""

    def children(margin: float) -> list[dict]:
        config = OptimizerConfig(mpf_margin=margin, mpf_margin_abs=0.0)
        found: list[dict] = []
        for seed in range(6):
            found.append(maximize(mpf, SPACE, exclude=found, seed=seed, config=config).x)
        return found

    def closest_pair(xs: list[dict]) -> float:
        z = SpaceEncoder(SPACE).encode_points(xs)
        d = np.linalg.norm(z[:, None] - z[None], axis=-1) + np.eye(len(xs)) * 9
        return float(d.min())

    spread, piled = children(0.2), children(0.0)
    assert sum(map(truly_feasible, spread)) >= 5
    assert closest_pair(spread) > 2 * closest_pair(piled)


def test_space_filling_stays_away_from_excluded_points() -> None:
    rng = np.random.default_rng(1)
    exclude = [{"dir": d, "pose": (0.5 * rng.random(2)).tolist()} for d in DIRS for _ in range(4)]
    x = space_filling(SPACE, exclude=exclude, seed=0)
    assert max(x["pose"]) > 0.5
    assert space_filling(SPACE, exclude=exclude, seed=0) == x


def test_ucb_finds_the_reward_peak_with_earlier_decisions_fixed() -> None:
    space = {
        "grasp": CategoricalDomain(choices=DIRS),
        "place": ContinuousDomain(low=[-1.0], high=[1.0]),
    }
    encoder = SpaceEncoder(space)
    rng = np.random.default_rng(2)
    seen = [{"grasp": "top", "place": [float(v)]} for v in rng.uniform(-1, 1, 12)]
    reward = -((encoder.columns(seen)["place"][:, 0] - 0.4) ** 2)
    fit = fit_regression(encoder.encode_points(seen), reward, seed=0, max_iters=60)
    fixed = {"grasp": "top"}
    found = maximize(
        ucb(fit.predictor, space, beta=0.01, fixed=fixed), space, fixed=fixed, exclude=seen, seed=0
    )
    assert found.x["grasp"] == "top" and abs(found.x["place"][0] - 0.4) < 0.15


def test_children_of_a_flat_acquisition_fill_the_inside_of_the_box() -> None:
    """Where the model cannot tell points apart (a flat surface, as before any data), the
    margin rule's spread treats the walls as mirrors: the children of one node fill the box
    like a space-filling design instead of sitting on its faces and corners."""
    box = {"pose": ContinuousDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0])}

    def flat(cols: dict) -> np.ndarray:
        return np.full(len(cols["pose"]), 0.3)

    config = OptimizerConfig(mpf_margin=0.1, mpf_margin_abs=0.025)
    children: list[dict] = []
    for seed in range(24):
        children.append(maximize(Scored(flat), box, exclude=children, seed=seed, config=config).x)
    poses = np.array([child["pose"] for child in children])
    near_a_wall = (np.minimum(poses, 1.0 - poses) < 0.05).any(axis=1)
    assert near_a_wall.mean() < 0.25
    middle = (np.abs(poses - 0.5) < 0.25).all(axis=1)
    assert middle.sum() >= 2


def test_without_walls_the_children_of_a_flat_acquisition_reach_the_faces() -> None:
    """`walls=False` (`knowledge.spread_walls=false`): the most spread point is measured from
    the other children alone, as the quasi-random baseline's Voronoi rule has it, so the
    second child of a node lies on the faces of its box, far from the first."""
    box = {"pose": ContinuousDomain(low=[0.0, 0.0, 0.0], high=[1.0, 1.0, 1.0])}

    def flat(cols: dict) -> np.ndarray:
        return np.full(len(cols["pose"]), 0.3)

    first = {"pose": [0.5, 0.5, 0.5]}
    for walls, on_a_face in ((False, True), (True, False)):
        config = OptimizerConfig(mpf_margin=0.1, mpf_margin_abs=0.025, spread_walls=walls)
        x = maximize(Scored(flat), box, exclude=[first], seed=3, config=config).x["pose"]
        near = min(min(v, 1.0 - v) for v in x) < 0.1
        assert near is on_a_face, (walls, x)


def test_a_batch_scores_each_candidate_once(mpf: MPF) -> None:
    """NSGA-II's start population and survivors are rows it was given or made: the
    acquisition (a GP per term) is run on each distinct row once per request."""
    scored: list[np.ndarray] = []

    def counting(cols: dict) -> np.ndarray:
        scored.append(np.column_stack([cols["dir"], cols["pose"]]))
        return mpf(cols)

    config = OptimizerConfig(pop_size=24, generations=3, raw_samples=128)
    found = maximize_batch(Scored(counting), SPACE, seed=4, config=config, n=3)
    rows = np.vstack(scored)
    assert len(found) == 3
    assert len(rows) == len(np.unique(rows, axis=0))
    assert len(rows) <= config.raw_samples + (config.generations - 1) * config.pop_size


def test_a_batch_answers_as_if_each_point_were_excluded_in_turn(mpf: MPF) -> None:
    children = [{"dir": "front", "pose": [0.8, 0.2]}, {"dir": "left", "pose": [0.7, 0.1]}]
    config = OptimizerConfig(mpf_margin=0.1, mpf_margin_abs=0.025)
    batch = maximize_batch(mpf, SPACE, exclude=children, seed=3, config=config, n=3)
    one_by_one = []
    for _ in range(3):
        chosen = [c.x for c in one_by_one]
        best = maximize_batch(mpf, SPACE, exclude=children + chosen, seed=3, config=config)
        one_by_one.append(best[0])
    assert batch[0].x == one_by_one[0].x
    assert all(b.x not in children for b in batch)
    assert len({str(b.x) for b in batch}) == 3


HINT_SPACE = {
    "dir": CategoricalDomain(choices=DIRS),
    "pose": ContinuousDomain(low=[0.0, 0.0, 0.0, 0.0], high=[2.0, 1.0, 1.0, 1.0]),
}
KNOWN = {"dir": "back", "pose": [1.3, 0.21, 0.77, 0.42]}  # where the constraint held once


def known_once() -> MPF:
    """A type with one feasible point, of the narrow reach a point not yet fitted has: a flat
    coin flip everywhere but next to it."""
    encoder = SpaceEncoder(HINT_SPACE)
    bump = PriorPredictor(encoder.encode_points([KNOWN]), np.zeros((0, encoder.dim)), 0.45, 0.02)
    bind = {k: k for k in HINT_SPACE}
    return MPF([ConstraintTerm.build("t", bump, HINT_SPACE, bind, {})])


def test_a_hinted_point_that_the_raw_samples_miss_is_found_and_answered_first() -> None:
    mpf = known_once()
    alone = maximize_batch(mpf, HINT_SPACE, seed=1, n=3)
    assert alone[0].value < 0.6  # the narrow bump is missed without the hint
    hinted = maximize_batch(mpf, HINT_SPACE, seed=1, n=3, hints=[{"pose": KNOWN["pose"]}, KNOWN])
    assert hinted[0].x["dir"] == KNOWN["dir"]
    assert hinted[0].x["pose"] == pytest.approx(KNOWN["pose"])
    assert hinted[0].value > 0.9
    assert all(s.x != hinted[0].x for s in hinted[1:])  # the rest of the batch spreads


def test_a_hint_is_never_an_excluded_point_nor_preferred_when_clearly_worse() -> None:
    mpf = known_once()
    excluded = maximize_batch(mpf, HINT_SPACE, exclude=[KNOWN], seed=1, hints=[KNOWN])
    assert excluded[0].x != KNOWN
    elsewhere = {"dir": "top", "pose": [0.1, 0.9, 0.1, 0.9]}
    worse = MPF(
        [
            ConstraintTerm.build(
                "t",
                PriorPredictor(
                    np.zeros((0, SpaceEncoder(HINT_SPACE).dim)),
                    SpaceEncoder(HINT_SPACE).encode_points([elsewhere]),
                ),
                HINT_SPACE,
                {k: k for k in HINT_SPACE},
                {},
            )
        ]
    )
    found = maximize_batch(worse, HINT_SPACE, seed=1, hints=[elsewhere])
    assert found[0].x != elsewhere and found[0].value > 0.4


def test_among_near_equal_candidates_a_preferred_hint_wins_over_the_most_spread() -> None:
    encoder = SpaceEncoder(HINT_SPACE)
    none = np.zeros((0, encoder.dim))
    bind = {k: k for k in HINT_SPACE}
    flat = MPF([ConstraintTerm.build("t", PriorPredictor(none, none), HINT_SPACE, bind, {})])
    child = {"dir": "back", "pose": [1.0, 0.5, 0.5, 0.5]}  # a sibling the answer keeps away from
    near_it = {"dir": "back", "pose": [1.1, 0.5, 0.5, 0.5]}
    spread = maximize_batch(flat, HINT_SPACE, exclude=[child], seed=2)
    assert spread[0].x != near_it
    scored = maximize_batch(flat, HINT_SPACE, exclude=[child], seed=2, hints=[near_it])
    assert scored[0].x == spread[0].x  # a hint only scored: the most spread still wins
    hinted = maximize_batch(flat, HINT_SPACE, exclude=[child], seed=2, hints=[near_it], preferred=1)
    assert hinted[0].x["pose"] == pytest.approx(near_it["pose"])


def test_terms_of_one_type_asked_together_score_as_each_alone(mpf: MPF) -> None:
    """One type bound three times (once with a fixed label, as a lookahead request binds it)
    beside another: the stacked call gives each term's own values."""
    space = {**SPACE, "dir2": SPACE["dir"], "pose2": SPACE["pose"]}
    a, b = (term.predictor for term in mpf.terms)
    terms = [
        ConstraintTerm.build("a", a, SPACE, BIND, {}),
        ConstraintTerm.build("b", b, SPACE, BIND, {}),
        ConstraintTerm.build("a", a, SPACE, {"dir": "dir2", "pose": "pose2"}, {}),
        ConstraintTerm.build("a", a, SPACE, {"dir": "dir", "pose": "pose2"}, {"dir": "top"}),
    ]
    rng = np.random.default_rng(3)
    points = [
        {"dir": DIRS[rng.integers(5)], "pose": rng.random(2).tolist()}
        | {"dir2": DIRS[rng.integers(5)], "pose2": rng.random(2).tolist()}
        for _ in range(40)
    ]
    cols = SpaceEncoder(space).columns(points)
    together = MPF(terms).per_term(cols)
    alone = np.stack([term.proba(cols) for term in terms])
    assert together.shape == (4, 40)
    np.testing.assert_array_equal(together, alone)
    assert not np.array_equal(together[0], together[2])

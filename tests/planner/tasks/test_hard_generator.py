"""The hard family: tight packings laid out at 45 % of the tray's usable area or more, drawn
deterministically from the suite's seed, each target kept only when its witness binding passes
every check in PyBullet (solvable), quasi-random-restarts' probes are slow (hard) and one of them
solves it (within search's reach); any other target is redrawn."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
import yaml

from planner.run import run_plan
from planner.sim import load_world
from planner.tasks import load_task
from planner.tasks.generator import HardProbe, generate_hard_suite, tight
from planner.tasks.generator.hard import METHOD, is_kept, probe_hardness
from planner.tasks.generator.layout import Rect, overlap
from planner.tasks.suites import suite_targets


def _texts(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): p.read_text() for p in sorted(root.rglob("*.yaml"))}


def _replays(path: Path, bindings: dict) -> bool:
    """Whether the binding passes every transition of the task, layer by layer, each given the
    decisions before it (its checks draw from them, as on the search's tree path)."""
    world = load_world(path, seed=0)
    try:
        state = world.initial_state()
        decisions = [d.var for d in world.skeleton.decisions]
        for index in range(len(world.skeleton.transitions)):
            path_bindings = {var: bindings[var] for var in decisions[: index + 1]}
            outcome = world.transition(index, path_bindings, state)
            if not outcome.ok:
                return False
            state = outcome.state
        return True
    finally:
        world.close()


@pytest.mark.parametrize(
    ("answers", "calls", "kept"),
    [
        ([None, None, 5], 3, True),  # the median is unsolved; the third decides the reach
        ([None, None, None], 3, False),  # no probe solves it: out of search's reach
        ([10, 20, None], 2, False),  # two fast of three: the third cannot make it hard
        ([None, 10, 600], 3, True),
        ([None, 10, 499], 3, False),
        ([500, 700, 10], 2, True),  # hard and solved whatever the third finds
    ],
)
def test_probes_stop_once_the_verdict_is_decided(
    answers: list[int | None], calls: int, kept: bool
) -> None:
    settings = HardProbe(seeds=3, max_rollouts=2000, hard_median=500)
    asked = []

    def probe(path: Path, seed: int, max_rollouts: int) -> int | None:
        asked.append((seed, max_rollouts))
        return answers[len(asked) - 1]

    found = probe_hardness(Path("unused"), [7, 8, 9], settings, probe)
    assert asked == [(7, 2000), (8, 2000), (9, 2000)][:calls]
    assert is_kept(found, settings) is kept


def test_packings_cover_the_drawn_share_of_the_floor_without_overlaps() -> None:
    rng = np.random.default_rng(3)
    laid = 0
    for _ in range(40):
        bodies = tight.draw_bodies(rng, int(rng.integers(5, 9)))
        assert [b.size[2] for b in bodies] == sorted(b.size[2] for b in bodies)
        packing = tight.lay_out(rng, bodies)
        if packing is None:
            continue
        laid += 1
        assert tight.FILL[0] <= packing.fill <= tight.FILL[1] + 1e-3
        covered = sum(b.size[0] * b.size[1] for b in bodies)
        floor = packing.size[0] * packing.size[1]
        room = tight.FINGER_ROOM * sum(min(b.size[:2]) for b in bodies)
        assert packing.fill == pytest.approx(covered / (floor - room))
        assert packing.floor_fill == pytest.approx(covered / floor)
        assert packing.floor_fill < packing.fill
        rects = [
            Rect(x, y, b.size[0], b.size[1])
            for (x, y), b in zip(packing.slots, bodies, strict=True)
        ]
        half_x, half_y = packing.size[0] / 2, packing.size[1] / 2
        for r in rects:
            assert abs(r.x) + r.sx / 2 <= half_x + 1e-6 and abs(r.y) + r.sy / 2 <= half_y + 1e-6
        for a, b in itertools.combinations(rects, 2):
            assert not overlap(a.grown(tight.ROW_GAP / 2 - 1e-4), b.grown(tight.ROW_GAP / 2 - 1e-4))
    assert laid >= 30


@pytest.mark.slow
def test_the_same_seed_writes_the_same_hard_suite_whose_witness_binds(tmp_path: Path) -> None:
    unchecked = HardProbe(check=False)
    generate_hard_suite(tmp_path / "a", 1, seed=5, settings=unchecked)
    generate_hard_suite(tmp_path / "b", 1, seed=5, settings=unchecked)
    assert _texts(tmp_path / "a") == _texts(tmp_path / "b")
    index = yaml.safe_load((tmp_path / "a" / "suite.yaml").read_text())
    (entry,) = index["targets"]
    assert index["difficulty"] == "hard" and entry["kind"] == "tight-pack"
    assert entry["fill"] >= 0.45 > entry["floor_fill"]
    target = tmp_path / "a" / entry["file"]
    task = load_task(str(target))
    assert 5 <= len(task.bodies) <= 8 and task.warnings == ()
    assert [p.relative_to(tmp_path / "a").as_posix() for p in suite_targets(tmp_path / "a")] == [
        entry["file"]
    ]
    for pre in task.predecessors:
        assert load_task(pre).role == "predecessor"
    assert entry["solved_by"]["method"] == "witness"
    assert _replays(target, entry["solved_by"]["bindings"])


@pytest.mark.slow
def test_a_target_that_is_not_hard_or_out_of_reach_is_redrawn(tmp_path: Path) -> None:
    # The first draw is fast for the probes, the second unsolved by all three, the third kept.
    answers = iter([12, 30, None, None, None, None, None, 800])

    def probe(path: Path, seed: int, max_rollouts: int) -> int | None:
        return next(answers)

    settings = HardProbe(seeds=3)
    made = generate_hard_suite(tmp_path, 1, seed=5, settings=settings, probe=probe)
    (entry,) = made["targets"]
    assert entry["attempts"] >= 3 and entry["probe_rollouts"] == [None, None, 800]
    assert len(entry["probe_seeds"]) == 3
    assert made["check"]["method"] == METHOD


@pytest.mark.slow
def test_a_generated_target_is_probed_hard_and_solvable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """At a scale a test affords (a looser packing, budgets of tens of rollouts): the probes'
    median is at least the bar, one probe solved it, each probe's seed reruns to the same
    count, and the witness binds it."""
    monkeypatch.setattr(tight, "FILL", (0.25, 0.3))
    settings = HardProbe(seeds=3, max_rollouts=60, hard_median=3)
    made = generate_hard_suite(tmp_path, 1, seed=5, settings=settings)
    (entry,) = made["targets"]
    assert is_kept(entry["probe_rollouts"], settings)
    target = tmp_path / entry["file"]
    for rollouts, seed in zip(entry["probe_rollouts"], entry["probe_seeds"], strict=True):
        again = run_plan(str(target), METHOD, seed, max_rollouts=60)
        assert (again.rollouts if again.solved else None) == rollouts
    assert _replays(target, entry["solved_by"]["bindings"])

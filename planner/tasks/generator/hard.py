"""The hard family (`cpkb generate --difficulty hard`): targets where binding search is slow.

Each workspace holds one target of each hard kind (so far: tight packing, `tight.py`) with its
predecessors. A target is kept only when it is solvable, a binding found and recorded (the
kind's own witness, played in the simulator); hard, the median over the probe seeds of
quasi-random-restarts (the strongest search without learning) at least `HardProbe.hard_median`
rollouts, an unsolved probe counting as more than any; and within search's reach, one probe at
least solved within its budget (a target only the witness binds measures no method).
A target that fails is redrawn whole, from the workspace's own stream of the suite's seed.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from planner.tasks.generator import tight
from planner.tasks.generator.build import WorkspaceDraft
from planner.tasks.generator.yaml_out import write_yaml

KINDS = ("tight-pack",)
METHOD = "quasi-random-restarts"  # the probes' search
TARGET_ATTEMPTS = 64  # draws of a target before the suite's seed is given up as barren


@dataclass(frozen=True)
class HardProbe:
    """The hardness check: `METHOD` on `seeds` seeds of `max_rollouts` each, whose median must
    be at least `hard_median` (an unsolved probe counts as more than any), one of them solved."""

    seeds: int = 3
    max_rollouts: int = 2000
    hard_median: int = 500
    check: bool = True


@dataclass
class HardTarget:
    kind: str
    file: str
    attempts: int
    fill: float  # of the tray's usable area (`tight.usable_area`)
    floor_fill: float
    witness: dict[str, Any]
    rollouts: list[int | None]
    seeds: list[int]


def is_hard(rollouts: list[int | None], settings: HardProbe) -> bool:
    """The median over every probe seed, the seeds not run counted as solved at once."""
    costs = [math.inf if r is None else r for r in rollouts]
    costs += [0] * (settings.seeds - len(costs))
    return statistics.median(costs) >= settings.hard_median


def is_kept(rollouts: list[int | None], settings: HardProbe) -> bool:
    """Hard, and solved by at least one probe."""
    return is_hard(rollouts, settings) and any(r is not None for r in rollouts)


def _decided(rollouts: list[int | None], settings: HardProbe) -> bool:
    """Whether the seeds left can no longer change the verdict: an answer counts only as
    unsolved, solved below `hard_median` or solved at it or above, so the three stand for all
    (and, the verdict blind to the order, their multisets for every way the rest may answer)."""
    classes = (None, 0, settings.hard_median)
    left = settings.seeds - len(rollouts)
    rests = itertools.combinations_with_replacement(classes, left)
    verdicts = {is_kept([*rollouts, *rest], settings) for rest in rests}
    return len(verdicts) == 1


Probe = Callable[[Path, int, int], int | None]


def quasi_random_probe(path: Path, seed: int, max_rollouts: int) -> int | None:
    """`METHOD`'s rollouts to the first binding (None: unsolved within `max_rollouts`)."""
    from planner.run import run_plan

    result = run_plan(str(path), METHOD, seed, max_rollouts=max_rollouts)
    return result.rollouts if result.solved else None


def probe_hardness(
    path: Path, seeds: list[int], settings: HardProbe, probe: Probe = quasi_random_probe
) -> list[int | None]:
    """The probes in seed order, until the verdict is decided."""
    found: list[int | None] = []
    for seed in seeds:
        found.append(probe(path, seed, settings.max_rollouts))
        if _decided(found, settings):
            break
    return found


def draw_tight_pack(
    rng: np.random.Generator, directory: Path, name: str
) -> tuple[tight.Packing, dict[str, Any]] | None:
    """One tight-packing workspace and its tasks written to `directory`, and its packing and
    witness binding; None when this draw has no room or no witness."""

    n = int(rng.integers(tight.BODIES[0], tight.BODIES[1] + 1))
    bodies = tight.draw_bodies(rng, n)
    packing = tight.lay_out(rng, bodies)
    if packing is None:
        return None
    ws = WorkspaceDraft(name)
    if tight.place_tray_and_sources(rng, ws, packing, n) is None:
        return None
    redrawn = tight.draw_bodies(rng, n)
    write_yaml(directory / "workspace.yaml", ws.to_yaml())
    for file, data in tight.tight_pack_files(name, bodies, redrawn).items():
        write_yaml(directory / file, data)
    slots = {f"body{i}": slot for i, slot in enumerate(packing.slots, start=1)}
    witness = tight.witness(directory / "tight_pack.yaml", slots)
    if witness is None:
        return None
    return packing, witness


def generate_hard_workspace(
    directory: Path,
    name: str,
    rng: np.random.Generator,
    settings: HardProbe,
    log: Callable[[str], None] = lambda _: None,
    probe: Probe = quasi_random_probe,
) -> list[HardTarget]:
    directory.mkdir(parents=True, exist_ok=True)
    for attempt in range(1, TARGET_ATTEMPTS + 1):
        drawn = draw_tight_pack(rng, directory, name)
        seeds = [int(s) for s in rng.integers(0, 2**31, size=settings.seeds)]
        if drawn is None:
            log(f"{name} tight-pack try {attempt}: no packing, room or witness")
            continue
        packing, witness = drawn
        fill, floor_fill = round(packing.fill, 4), round(packing.floor_fill, 4)
        rollouts: list[int | None] = []
        if settings.check:
            rollouts = probe_hardness(directory / "tight_pack.yaml", seeds, settings, probe)
            log(
                f"{name} tight-pack try {attempt}: fill {fill:.2f} (floor {floor_fill:.2f}),"
                f" {METHOD} {rollouts}"
            )
            if not is_kept(rollouts, settings):
                continue
        file = f"{name}/tight_pack.yaml"
        probed = seeds[: len(rollouts)]
        return [
            HardTarget("tight-pack", file, attempt, fill, floor_fill, witness, rollouts, probed)
        ]
    raise RuntimeError(f"{name}: no hard target in {TARGET_ATTEMPTS} draws")

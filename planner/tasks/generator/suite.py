"""A generated suite: workspaces, each with a desk-like, a regrasp-like and a pack-like target.

Every target is probed with quasi-random (`planner.run.run_plan`): it must be solved within the
rollout budget on most probe seeds and need more than a handful of rollouts in the median; a
target that fails is redrawn with its own geometry and bodies, and a workspace whose targets
keep failing is redrawn whole. Everything random comes from the suite's seed.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from planner.tasks.generator.build import (
    Shared,
    WorkspaceDraft,
    body_entry,
    draw_shared,
    pack_area,
    pack_layers,
    pick_place_layers,
    regrasp_layers,
)
from planner.tasks.generator.hard import (
    METHOD as HARD_METHOD,
)
from planner.tasks.generator.hard import (
    HardProbe,
    Probe,
    generate_hard_workspace,
    quasi_random_probe,
)
from planner.tasks.generator.layout import draw_body
from planner.tasks.generator.yaml_out import write_yaml

KINDS = ("desk", "regrasp", "pack")
# Redraws of a target's own bodies (and, for pack, its tray) before the workspace is redrawn:
# a desk that keeps failing mostly has a cubby out of reach, which only a new workspace fixes.
KIND_ATTEMPTS = {"desk": 2, "regrasp": 3, "pack": 4}
# A suite's seed must give a suite: some seeds draw several workspaces in a row whose desk or
# pack never passes. Raising the cap changes no suite that an earlier cap produced (the draws
# are the same up to the first that passes).
WORKSPACE_ATTEMPTS = 32
SUITE_FILE = "suite.yaml"


class GenerationError(RuntimeError):
    """No layout passed the checks within the attempts allowed."""


@dataclass(frozen=True)
class ProbeSettings:
    """The solvability check: quasi-random on `seeds` seeds, `max_rollouts` each."""

    seeds: int = 3
    max_rollouts: int = 500
    trivial: float = 3.0  # a median of rollouts at or below this is too easy
    check: bool = True


@dataclass
class TargetReport:
    kind: str
    file: str
    attempts: int
    rollouts: list[int | None] = field(default_factory=list)  # None: not solved
    seeds: list[int] = field(default_factory=list)  # the probes' seeds, to rerun them


Files = dict[str, dict[str, Any]]


def _task(name: str, kind: str, role: str, description: str, **parts: Any) -> dict[str, Any]:
    return {
        "task": name,
        "role": role,
        "kind": kind,
        "description": description,
        "workspace": "workspace.yaml",
        **parts,
    }


def desk_files(rng: np.random.Generator, ws: str) -> Files:
    """Pick from the cluttered corner (two of its three boxes), place on the shelf board; the
    predecessor moves another body, or the same body from the free start."""
    missing = str(rng.choice(["left", "back", "right"]))
    obstacles = [f"clutter_{s}" for s in ("left", "back", "right") if s != missing]
    obstacles.append("shelf_box")
    body, other = draw_body(rng), draw_body(rng)
    moves_other = bool(rng.integers(2))
    pre_body, pre_start = (other, "pose_start") if moves_other else (body, "pose_alt")
    goal = {"goal": ["On(body, region_shelf)"]}
    return {
        "desk.yaml": _task(
            f"{ws}-desk",
            "desk",
            "target",
            "Move the body from the cluttered corner onto the shelf board, around the box there.",
            predecessors=["desk_pre.yaml"],
            obstacles=obstacles,
            bodies={"body": body_entry(body, "pose_start")},
            skeleton=pick_place_layers("body", "pose_start", "region_shelf"),
            **goal,
        ),
        "desk_pre.yaml": _task(
            f"{ws}-desk_pre",
            "desk",
            "predecessor",
            "Predecessor of desk: "
            + ("another body from the same corner." if moves_other else "from the free start."),
            obstacles=obstacles,
            bodies={"body": body_entry(pre_body, pre_start)},
            skeleton=pick_place_layers("body", pre_start, "region_shelf"),
            **goal,
        ),
    }


def regrasp_files(rng: np.random.Generator, ws: str) -> Files:
    """Boxed in on three sides: put the body down in the free area, grasp it again, shelve it.
    Predecessors: another body into the free area; the same body from the free start to the
    shelf."""
    obstacles = ["clutter_left", "clutter_back", "clutter_right", "free_box", "shelf_box"]
    body, other = draw_body(rng, (0.12, 0.2)), draw_body(rng, (0.12, 0.2))
    return {
        "regrasp.yaml": _task(
            f"{ws}-regrasp",
            "regrasp",
            "target",
            "The body is boxed in on three sides: set it down in the free area, grasp it "
            "again, and place it on the shelf board.",
            predecessors=["regrasp_pre1.yaml", "regrasp_pre2.yaml"],
            obstacles=obstacles,
            bodies={"body": body_entry(body, "pose_start")},
            skeleton=regrasp_layers("pose_start", "region_free", "region_shelf"),
            goal=["On(body, region_shelf)"],
        ),
        "regrasp_pre1.yaml": _task(
            f"{ws}-regrasp_pre1",
            "regrasp",
            "predecessor",
            "Predecessor of regrasp: another body from the boxed-in start into the free area.",
            obstacles=obstacles,
            bodies={"body": body_entry(other, "pose_start")},
            skeleton=pick_place_layers("body", "pose_start", "region_free"),
            goal=["On(body, region_free)"],
        ),
        "regrasp_pre2.yaml": _task(
            f"{ws}-regrasp_pre2",
            "regrasp",
            "predecessor",
            "Predecessor of regrasp: the body from the free start onto the shelf board.",
            obstacles=obstacles,
            bodies={"body": body_entry(body, "pose_alt")},
            skeleton=pick_place_layers("body", "pose_alt", "region_shelf"),
            goal=["On(body, region_shelf)"],
        ),
    }


def pack_files(rng: np.random.Generator, ws: str, n: int) -> Files:
    """`n` boxes, tallest first, into the tray with top grasps; predecessors pack redrawn
    boxes: the first alone, then the others."""
    bodies = sorted((draw_body(rng) for _ in range(n)), key=lambda b: -b.size[2])
    redrawn = sorted((draw_body(rng) for _ in range(n)), key=lambda b: -b.size[2])
    names = [f"body{i}" for i in range(1, n + 1)]

    def entries(drawn: list, chosen: list[str]) -> dict[str, Any]:
        return {
            name: body_entry(drawn[names.index(name)], f"pose_src{name[4:]}", names.index(name))
            for name in chosen
        }

    rest = names[1:]
    return {
        "pack.yaml": _task(
            f"{ws}-pack",
            "pack",
            "target",
            f"Move the {n} boxes (tallest first) into the tray with top grasps, leaving room "
            "for the ones still to come.",
            predecessors=["pack_pre1.yaml", "pack_pre2.yaml"],
            obstacles=["tray"],
            bodies=entries(bodies, names),
            skeleton=pack_layers(names, "region_tray"),
            goal=[f"On({b}, region_tray)" for b in names],
        ),
        "pack_pre1.yaml": _task(
            f"{ws}-pack_pre1",
            "pack",
            "predecessor",
            "Predecessor of pack: another first box alone into the tray.",
            obstacles=["tray"],
            bodies=entries(redrawn, names[:1]),
            skeleton=pack_layers(names[:1], "region_tray"),
            goal=["On(body1, region_tray)"],
        ),
        "pack_pre2.yaml": _task(
            f"{ws}-pack_pre2",
            "pack",
            "predecessor",
            "Predecessor of pack: other boxes in place of the later ones, into the tray.",
            obstacles=["tray"],
            bodies=entries(redrawn, rest),
            skeleton=pack_layers(rest, "region_tray"),
            goal=[f"On({b}, region_tray)" for b in rest],
        ),
    }


def probe(path: Path, settings: ProbeSettings, seeds: list[int]) -> list[int | None]:
    """Quasi-random's rollouts to the first binding on each probe seed (None: not solved);
    stops early once most seeds can no longer be solved."""
    from planner.run import run_plan

    found: list[int | None] = []
    for seed in seeds:
        result = run_plan(str(path), "quasi-random", seed, max_rollouts=settings.max_rollouts)
        found.append(result.rollouts if result.solved else None)
        if sum(r is None for r in found) * 2 >= settings.seeds:
            break
    return found


def probe_text(rollouts: list[int | None], settings: ProbeSettings) -> str:
    """The probes' outcome for a person: `quasi-random rollouts 12, unsolved in 500, 40`."""
    shown = [f"unsolved in {settings.max_rollouts}" if r is None else str(r) for r in rollouts]
    return "quasi-random rollouts " + ", ".join(shown)


def passes(rollouts: list[int | None], settings: ProbeSettings) -> bool:
    solved = [r for r in rollouts if r is not None]
    if len(solved) * 2 <= settings.seeds:
        return False
    costs = [math.inf if r is None else r for r in rollouts]
    return statistics.median(costs) > settings.trivial


def _kind_files(kind: str, rng: np.random.Generator, name: str, n_pack: int) -> Files:
    if kind == "desk":
        return desk_files(rng, name)
    if kind == "regrasp":
        return regrasp_files(rng, name)
    return pack_files(rng, name, n_pack)


def _redraw_geometry(
    kind: str, rng: np.random.Generator, shared: Shared, ws: WorkspaceDraft
) -> int:
    """Fresh geometry of a kind's own: the tray and the boxes' start for pack."""
    if kind == "pack":
        for pose in [p for p in ws.poses if p.startswith("pose_src")]:
            del ws.poses[pose]
        n = int(rng.integers(2, 5))
        if not pack_area(rng, shared.cubby, n, ws):
            raise GenerationError("no room for a tray")
        return n
    return 0


def generate_workspace(
    directory: Path,
    name: str,
    rng: np.random.Generator,
    settings: ProbeSettings,
    log: Callable[[str], None] = lambda _: None,
) -> list[TargetReport]:
    from planner.tasks import load_task

    directory.mkdir(parents=True, exist_ok=True)
    for attempt in range(1, WORKSPACE_ATTEMPTS + 1):
        ws = WorkspaceDraft(name)
        try:
            shared = draw_shared(rng, ws)
        except RuntimeError:
            continue
        reports: list[TargetReport] = []
        for kind in KINDS:
            for tries in range(1, KIND_ATTEMPTS[kind] + 1):
                try:
                    n_pack = _redraw_geometry(kind, rng, shared, ws)
                except GenerationError:
                    break
                write_yaml(directory / "workspace.yaml", ws.to_yaml())
                files = _kind_files(kind, rng, name, n_pack)
                for file, data in files.items():
                    write_yaml(directory / file, data)
                target = directory / f"{kind}.yaml"
                if load_task(str(target)).warnings:
                    continue
                seeds = [int(s) for s in rng.integers(0, 2**31, size=settings.seeds)]
                rollouts = probe(target, settings, seeds) if settings.check else []
                if settings.check:
                    log(f"{name} {kind} try {tries}: {probe_text(rollouts, settings)}")
                if not settings.check or passes(rollouts, settings):
                    seeds = seeds[: len(rollouts)]
                    reports.append(
                        TargetReport(kind, f"{name}/{kind}.yaml", tries, rollouts, seeds)
                    )
                    break
            else:
                break
            if len(reports) < KINDS.index(kind) + 1:
                break
        if len(reports) == len(KINDS):
            return reports
        log(f"{name}: workspace attempt {attempt} failed, redrawing it")
    raise GenerationError(f"{name}: no workspace passed the checks in {WORKSPACE_ATTEMPTS} draws")


def generate_suite(
    out: Path,
    workspaces: int,
    seed: int,
    settings: ProbeSettings = ProbeSettings(),
    log: Callable[[str], None] = lambda _: None,
) -> dict[str, Any]:
    """Write `workspaces` workspaces under `out` (ws00, ws01, ...) and `out/suite.yaml`, the
    index: the targets with their probe results, and how the suite was made."""
    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    streams = np.random.SeedSequence(seed).spawn(workspaces)
    targets: list[dict[str, Any]] = []
    for index, stream in enumerate(streams):
        name = f"ws{index:02d}"
        for report in generate_workspace(
            out / name, name, np.random.default_rng(stream), settings, log
        ):
            targets.append(
                {
                    "file": report.file,
                    "kind": report.kind,
                    "attempts": report.attempts,
                    "probe_rollouts": report.rollouts,
                    "probe_seeds": report.seeds,
                }
            )
    index_data = {
        "seed": seed,
        "workspaces": workspaces,
        "check": {
            "enabled": settings.check,
            "method": HARD_METHOD,
            "probe_seeds": settings.seeds,
            "max_rollouts": settings.max_rollouts,
            "trivial_median": settings.trivial,
        },
        "targets": targets,
    }
    write_yaml(out / SUITE_FILE, index_data)
    return index_data | {"wall_s": time.perf_counter() - started}


def generate_hard_suite(
    out: Path,
    workspaces: int,
    seed: int,
    settings: HardProbe | None = None,
    log: Callable[[str], None] = lambda _: None,
    probe: Probe = quasi_random_probe,
) -> dict[str, Any]:
    """The hard family's suite (`planner.tasks.generator.hard`), written like `generate_suite`'s;
    the index also records each target's packing fill (of the usable area and of the floor) and
    the binding that proves it solvable."""
    settings = settings or HardProbe()
    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    streams = np.random.SeedSequence(seed).spawn(workspaces)
    targets: list[dict[str, Any]] = []
    for index, stream in enumerate(streams):
        name = f"ws{index:02d}"
        try:
            made = generate_hard_workspace(
                out / name, name, np.random.default_rng(stream), settings, log, probe
            )
        except RuntimeError as exc:
            raise GenerationError(str(exc)) from None
        targets += [
            {
                "file": t.file,
                "kind": t.kind,
                "attempts": t.attempts,
                "fill": t.fill,
                "floor_fill": t.floor_fill,
                "probe_rollouts": t.rollouts,
                "probe_seeds": t.seeds,
                "solved_by": {"method": "witness", "bindings": t.witness},
            }
            for t in made
        ]
    index_data = {
        "seed": seed,
        "workspaces": workspaces,
        "difficulty": "hard",
        "check": {
            "enabled": settings.check,
            "method": HARD_METHOD,
            "probe_seeds": settings.seeds,
            "max_rollouts": settings.max_rollouts,
            "hard_median": settings.hard_median,
        },
        "targets": targets,
    }
    write_yaml(out / SUITE_FILE, index_data)
    return index_data | {"wall_s": time.perf_counter() - started}

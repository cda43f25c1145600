"""Skeletons for a goal-only task: a PDDL domain from cpkb's operators, solved by K*.

cpkb's operators compose into two symbolic actions: *pick* (`Sample-grasp`, then `Inv-kin`,
`Plan-motion`, `Move-Pick`) and *place* (`Sample-pose`, then `Inv-kin`, `Plan-motion`,
`Move-Place`), each on a region or on a movable body's top face (stacking). The domain says
nothing of geometry: a body walled in can be picked symbolically, and the binding search finds
out that it cannot. So the planner is asked for the `k` cheapest plans, not one (top-k
planning), and the search shares its effort among them (`planner.goals.search`).

The planner is K* (`kstar-planner` on PyPI, IBM Research, GPL-3: Fast Downward's top-k
search). It runs as its own process (`python -m kstar_planner`), so cpkb (MIT) only exchanges
PDDL text and plans with it.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from planner.tasks.schema import Task, TaskError, smaller, start_support

# `towers` (Hanoi's rules, `Task.stacking`): a body stacks only on a larger one (static
# `smaller` facts from the bodies' sizes) and a region holds one body (`free`).
_TOWERS = {"pick": "(free ?r)", "place": "(not (free ?r))", "stack": "(smaller ?b ?s)"}


def domain(stacking: str) -> str:
    """The PDDL domain of picks and places; `stacking` as `Task.stacking` says."""
    towers = stacking == "towers"
    extra = {k: f" {v}" if towers else "" for k, v in _TOWERS.items()}
    place_pre = " (free ?r)" if towers else ""
    return f"""\
(define (domain cpkb)
  (:requirements :strips :typing)
  (:types body region)
  (:predicates (on ?b - body ?r - region) (on-body ?b - body ?s - body)
               (holding ?b - body) (handempty) (clear ?b - body)
               (free ?r - region) (smaller ?b - body ?s - body))
  (:action pick
    :parameters (?b - body ?r - region)
    :precondition (and (handempty) (on ?b ?r) (clear ?b))
    :effect (and (holding ?b) (not (handempty)) (not (on ?b ?r)) (not (clear ?b)){extra["pick"]}))
  (:action unstack
    :parameters (?b - body ?s - body)
    :precondition (and (handempty) (on-body ?b ?s) (clear ?b))
    :effect (and (holding ?b) (not (handempty)) (not (on-body ?b ?s)) (not (clear ?b))
                 (clear ?s)))
  (:action place
    :parameters (?b - body ?r - region)
    :precondition (and (holding ?b){place_pre})
    :effect (and (on ?b ?r) (handempty) (clear ?b) (not (holding ?b)){extra["place"]}))
  (:action stack
    :parameters (?b - body ?s - body)
    :precondition (and (holding ?b) (clear ?s){extra["stack"]})
    :effect (and (on-body ?b ?s) (handempty) (clear ?b) (not (holding ?b)) (not (clear ?s))))
)
"""


PLANNER_TIMEOUT_S = 60
ASK = 4  # plans asked of K* per plan kept
_PLAN = re.compile(r"^Plan \d+, of cost ([\d.]+)$")
_ACTION = re.compile(r"^\d+\. \((\S+) (\S+) (\S+)\)$")


@dataclass(frozen=True)
class Move:
    """One pick and place: `body` from where it stands to `place` (a region or a body)."""

    body: str
    place: str


@dataclass(frozen=True)
class Plan:
    moves: tuple[Move, ...]
    cost: float


def _name(text: str) -> str:
    """A task name as a PDDL object (PDDL is case-insensitive; K* answers in lower case)."""
    return text.lower()


def problem(task: Task) -> str:
    """The task's start and goal as a PDDL problem: every body on its start pose's region or on
    the body it starts on, clear when nothing starts on it; with `stacking: towers`, the
    regions no body starts on are free and `smaller` says which body may stand on which."""
    regions = " ".join(_name(r) for r in task.workspace.regions)
    bodies = " ".join(_name(b) for b in task.bodies)
    below = {start_support(task.workspace, task.bodies, b): b for b in task.bodies}
    start = ["(handempty)"]
    for b in task.bodies:
        support = start_support(task.workspace, task.bodies, b)
        fact = "on-body" if support in task.bodies else "on"
        start.append(f"({fact} {_name(b)} {_name(support)})")
        if b not in below:
            start.append(f"(clear {_name(b)})")
    if task.stacking == "towers":
        start += [f"(free {_name(r)})" for r in task.workspace.regions if r not in below]
        start += [
            f"(smaller {_name(a)} {_name(b)})"
            for a, body_a in task.bodies.items()
            for b, body_b in task.bodies.items()
            if smaller(body_a, body_b)
        ]
    goals = [
        f"(on {_name(g.body)} {_name(g.region)})"
        if g.region in task.workspace.regions
        else f"(on-body {_name(g.body)} {_name(g.region)})"
        for g in task.goal
    ]
    return (
        f"(define (problem {_name(task.name)}) (:domain cpkb)\n"
        f"  (:objects {bodies} - body {regions} - region)\n"
        f"  (:init {' '.join(start)})\n"
        f"  (:goal (and (handempty) {' '.join(goals)})))\n"
    )


def parse_plans(text: str, names: dict[str, str]) -> list[Plan]:
    """K*'s printed plans as moves, names given back their task spelling."""
    plans: list[Plan] = []
    actions: list[tuple[str, str, str]] = []
    cost = 0.0

    def close() -> None:
        if actions:
            puts = [Move(names[b], names[p]) for a, b, p in actions if a in ("place", "stack")]
            plans.append(Plan(tuple(puts), cost))

    for line in text.splitlines():
        line = line.strip()
        if (m := _PLAN.match(line)) is not None:
            close()
            actions, cost = [], float(m.group(1))
        elif (m := _ACTION.match(line)) is not None:
            actions.append((m.group(1), m.group(2), m.group(3)))
    close()
    return plans


def redundant(task: Task, plan: Plan) -> bool:
    """Whether a move puts a body back on the place it was taken from (a symbolic no-op: cpkb
    does not shift a body within its region), or back on the place it stood before its previous
    move with no other body moved in between (the two moves together are such a no-op), or the
    goal holds before the last move (the moves after it cannot help; the shorter plan is among
    the others)."""
    where = {b: start_support(task.workspace, task.bodies, b) for b in task.bodies}
    left: Move | None = None  # the previous move's body and the place it was taken from
    for i, move in enumerate(plan.moves):
        if where[move.body] == move.place or left == move:
            return True
        left = Move(move.body, where[move.body])
        where[move.body] = move.place
        if i < len(plan.moves) - 1 and all(where[g.body] == g.region for g in task.goal):
            return True
    return False


def top_plans(task: Task, k: int) -> list[Plan]:
    """The `k` cheapest plans K* finds for the task, the redundant ones left out, cheapest
    first (K*'s order among plans of one cost). K* is asked for `ASK` times `k`: most of its
    cheapest plans are redundant, and the ones that move a body away and back come after them
    (the non-monotonic problem's)."""
    with PlanSearch(task, k) as search:
        return search.plans()


class PlanSearch:
    """K* started on the task in its own process, so that the caller does other work (the
    scene, the knowledge base) while it plans; `plans()` waits for it (`top_plans`)."""

    def __init__(self, task: Task, k: int) -> None:
        self.task, self.k = task, k
        self._folder = tempfile.TemporaryDirectory(prefix="cpkb-pddl-")
        folder = Path(self._folder.name)
        domain_file, prob = folder / "domain.pddl", folder / "problem.pddl"
        domain_file.write_text(domain(task.stacking))
        prob.write_text(problem(task))
        command = [
            *(sys.executable, "-m", "kstar_planner"),
            *(str(domain_file), str(prob), "-k", str(ASK * k)),
        ]
        self._process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=folder
        )

    def plans(self) -> list[Plan]:
        task = self.task
        try:
            stdout, stderr = self._process.communicate(timeout=PLANNER_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise TaskError(
                f"{task.source}: goal: the PDDL planner found no plan in {PLANNER_TIMEOUT_S} s"
            ) from None
        names = {_name(n): n for n in (*task.workspace.regions, *task.bodies)}
        found = parse_plans(stdout, names)
        if not found:
            detail = stderr.strip().splitlines()[-1:] or ["no plan"]
            raise TaskError(f"{task.source}: goal: the PDDL planner found no plan ({detail[0]})")
        plans = [p for p in found if not redundant(task, p)]
        if not plans:
            raise TaskError(f"{task.source}: goal: every plan the PDDL planner found is redundant")
        return sorted(plans, key=lambda p: p.cost)[: self.k]

    def close(self) -> None:
        if self._process.poll() is None:
            self._process.kill()
            self._process.wait()
        self._folder.cleanup()

    def __enter__(self) -> PlanSearch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

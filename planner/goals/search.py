"""Binding search across the skeletons of a goal-only task, effort shared as eTAMP does.

K* gives the cheapest plans (`planner.goals.pddl`); each becomes a skeleton with its own
PW-UCT tree, world (one PyBullet scene shared by all) and, for the knowledge methods, its own
session on the one knowledge base. The trees take turns of `TURN` rollouts: the next turn goes
to the skeleton with the least `priority`, effort spent per progress made, weighed by its moves
beyond the cheapest plan's. A skeleton whose rollouts keep failing early yields to the next; one
that comes close (its deepest rollout far down its layers) is revisited. Skeletons are opened
(their world and tree built) by progressive widening, as eTAMP widens its skeleton space: the
unopened ones compete for a turn only while the opened ones number at most the square root of
the turns taken (or are all exhausted). Failures are posted as CP points typed by their
causal graphs, which name kinds and bodies, never the skeleton, so what one skeleton's failures
taught steers the others' suggestions.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

from contract.models import MAX_LABEL
from planner.goals.pddl import Plan, PlanSearch
from planner.goals.skeletons import describe, skeleton_task
from planner.search import PWUCT, SearchProgress
from planner.search import samplers as sampler_registry
from planner.tasks.schema import Task
from planner.world import TransitionOutcome

PLANS = 40  # plans taken from K*, cheapest first (the redundant ones are dropped)
TURN = 10  # rollouts a skeleton runs before the next is chosen
PROGRESS_FLOOR = 0.25  # the progress credited to a skeleton not yet run


@dataclass
class Branch:
    """One skeleton's search: its plan, and once opened, its world, sampler and tree."""

    plan: Plan
    index: int
    world: Any = None
    sampler: Any = None
    session: Any = None
    search: PWUCT | None = None
    spent: int = 0
    progress: float = 0.0  # the deepest rollout's share of the skeleton's layers
    exhausted: bool = False
    found: dict[str, Any] | None = None
    solved_before: bool = False  # the knowledge base holds a binding list found for it


class Blame:
    """Counts the movable bodies failed checks name as culprits (other than the body the
    check acts on), and passes every transition on to the search's own observer."""

    def __init__(self, movable: set[str]) -> None:
        self.movable = movable
        self.named: set[str] = set()

    def observe(self, inner: Any) -> Any:
        blame = self

        class Observer:
            def on_transition(
                self, index: int, bindings: dict, outcome: TransitionOutcome, rollout: int
            ) -> None:
                failed = outcome.failed
                if failed is not None:
                    actor = failed.call.args[0] if failed.call.args else None
                    blame.named.update(
                        c.body
                        for c in failed.culprits
                        if c.body in blame.movable and c.body != actor
                    )
                if inner is not None:
                    inner.on_transition(index, bindings, outcome, rollout)

            def on_rollout_end(self, rollout: int) -> None:
                if inner is not None:
                    inner.on_rollout_end(rollout)

        return Observer()


def priority(branch: Branch, fewest_moves: int, blamed: set[str]) -> float:
    """Effort spent (with the coming turn) per progress made, times one plus the moves beyond
    the cheapest plan's, a move of a body some failure collided with not counted (it may clear
    the way, or put the body back): the least goes next; an exhausted tree never does. A
    skeleton some earlier run solved (a binding list of it is stored) goes first: one rollout,
    which follows that binding list, then, if that failed, a whole turn."""
    if branch.exhausted:
        return float("inf")
    if branch.solved_before and branch.spent <= 1:
        return 0.0
    clearing = sum(move.body in blamed for move in branch.plan.moves)
    extra = max(0, len(branch.plan.moves) - fewest_moves - clearing)
    progress = branch.progress if branch.spent else PROGRESS_FLOOR
    return (branch.spent + TURN) * (1 + extra) / max(progress, 1e-3)


def next_branch(branches: list[Branch], turns: int, fewest: int, blamed: set[str]) -> Branch:
    """The skeleton to run the next turn: the least `priority` among the opened ones, or among
    all while the opened number at most the square root of the turns taken (or are all
    exhausted); the cheaper plan on a tie."""
    opened = [b for b in branches if b.search is not None]
    candidates = opened
    if len(opened) ** 2 <= turns or all(b.exhausted for b in opened):
        candidates = branches
    return min(candidates, key=lambda b: (priority(b, fewest, blamed), b.index))


def stored_skeletons(client: Any, kb: str, task: Task) -> set[str]:
    """The digests of the skeletons the knowledge base holds binding lists for, found by
    earlier runs of the task (found bindings are keyed by the task and the skeleton's digest)."""
    return {b.skeleton for b in client.bindings(kb, task=task.name[:MAX_LABEL]).bindings}


def solved_before(stored: set[str], task: Task, plans: list[Plan]) -> list[bool]:
    """Per plan, whether its skeleton's digest is among `stored`."""
    from planner.knowledge.found import skeleton_digest
    from planner.tasks import build_skeleton

    return [
        bool(stored) and skeleton_digest(build_skeleton(skeleton_task(task, p))) in stored
        for p in plans
    ]


def plan_goal(
    request: Any, task: Task, started: float, progress: Callable[[Any], None] | None
) -> Any:
    """`run_plan` for a task without a skeleton (see the module docstring)."""
    from planner.knowledge.stats import KnowledgeStats
    from planner.result import PlanResult, Progress
    from planner.sim.scene import Scene
    from planner.sim.world import PyBulletWorld

    blame = Blame(set(task.bodies))
    config = request.config
    knowledge = sampler_registry.uses_knowledge(request.method)
    with ExitStack() as stack:
        # K* plans in its own process while the knowledge base is asked and the scene loads.
        pending = stack.enter_context(PlanSearch(task, PLANS))
        client = None
        stored: set[str] = set()
        if knowledge:
            from client import CpkbClient

            if request.kb_url is None:
                raise ValueError(f"{request.method} needs a knowledge base: give kb_url")
            client = stack.enter_context(CpkbClient(request.kb_url, token=request.token))
            client.create_kb(request.kb, exist_ok=True)
            if config.knowledge.follow_found:
                stored = stored_skeletons(client, request.kb, task)
        scene = Scene(task, gui=request.gui)
        stack.callback(scene.close)
        plans = pending.plans()
        branches = [Branch(plan, i) for i, plan in enumerate(plans)]
        for branch, before in zip(branches, solved_before(stored, task, plans), strict=True):
            branch.solved_before = before
        fewest = min(len(p.moves) for p in plans)
        ready_s = time.perf_counter() - started

        def open_branch(branch: Branch) -> None:
            skeleton = skeleton_task(task, branch.plan)
            world = PyBulletWorld(skeleton, seed=request.seed, gui=request.gui, scene=scene)
            branch.world = world
            if client is not None:
                branch.session = request.knowledge_session(client, world)
                stack.callback(branch.session.close)
                if branch.solved_before:
                    # Its first rollout follows the stored binding list; the types are matched
                    # only if that fails (prematching costs more than the rollout).
                    branch.session.read_found()
                elif config.cp_bo.prematch:
                    branch.session.prematch()
            branch.sampler = sampler_registry.make(
                request.method,
                seed=request.seed,
                world=world,
                knowledge=branch.session,
                config=config,
            )
            stack.callback(branch.sampler.close)
            branch.search = PWUCT(
                world,
                branch.sampler,
                seed=request.seed,
                config=config.search,
                observer=blame.observe(branch.session),
            )

        total, best, turns = 0, 0.0, 0
        winner: Branch | None = None
        deadline = None if request.time_budget_s is None else started + request.time_budget_s
        while total < request.max_rollouts and (deadline is None or time.perf_counter() < deadline):
            branch = next_branch(branches, turns, fewest, blame.named)
            if branch.exhausted:
                break
            turns += 1
            if branch.search is None:
                open_branch(branch)
            search = branch.search
            assert search is not None
            turn = min(TURN, request.max_rollouts - total)
            if branch.solved_before and branch.spent == 1 and branch.session is not None:
                if config.cp_bo.prematch:
                    branch.session.prematch(found=False)
            elif branch.solved_before and not branch.spent:
                turn = 1

            def report(p: SearchProgress, base: int = total - branch.spent) -> None:
                if progress is not None:
                    progress(
                        Progress(
                            rollouts=base + p.rollouts,
                            max_rollouts=request.max_rollouts,
                            best_depth=p.best_depth,  # a share of the running skeleton's layers
                            solved=p.solved,
                            types_active=0,
                            types_activated=0,
                            elapsed_s=time.perf_counter() - started,
                        )
                    )

            outcome = search.run(
                branch.spent + turn, stop_at_first=True, progress=report, deadline=deadline
            )
            total += outcome.rollouts_spent - branch.spent
            branch.spent = outcome.rollouts_spent
            branch.progress = outcome.best_depth  # already a share of the layers
            best = max(best, branch.progress)
            branch.exhausted = outcome.exhausted
            if outcome.solved:
                branch.found = outcome.bindings
                winner = branch
                break
        opened = [b for b in branches if b.search is not None]
        # A stored binding list followed in the first rollout is stored already.
        replayed = winner is not None and winner.solved_before and winner.spent == 1
        if (
            winner is not None
            and winner.session is not None
            and winner.found is not None
            and not replayed
        ):
            winner.session.add_found(winner.found, winner.spent)
        sessions = [b.session for b in opened if b.session is not None]
        tried = ", ".join(f"{b.index + 1}: {b.spent}" for b in opened)
        notes = [
            f"{len(plans)} skeletons from K*; rollouts by skeleton {tried}",
            f"{ready_s:.2f} s before the first turn (K*, the scene, the knowledge base)",
        ]
        if winner is None and deadline is not None and time.perf_counter() >= deadline:
            notes.append("time budget reached")
        earlier = [str(b.index + 1) for b in branches if b.solved_before]
        if earlier:
            notes.append(f"skeletons solved by earlier runs: {', '.join(earlier)}")
        if winner is not None:
            notes.append(
                f"solved by skeleton {winner.index + 1} of {len(plans)} ({describe(winner.plan)})"
            )
        return PlanResult(
            task=task.name,
            method=request.method,
            seed=request.seed,
            solved=winner is not None,
            rollouts=total,
            rollouts_spent=total,
            wall_s=time.perf_counter() - started,
            sim_s=sum(b.search.sim_s for b in opened if b.search is not None),
            sample_s=sum(b.search.sample_s for b in opened if b.search is not None),
            bindings=winner.found if winner is not None else None,
            best_depth=best,
            knowledge=KnowledgeStats(
                types_activated=sum(s.stats.types_activated for s in sessions),
                points_posted=sum(s.points_posted for s in sessions),
                kb_s=sum(s.stats.kb_s for s in sessions),
            ),
            kb=request.kb if knowledge else None,
            notes=notes,
            config=config.to_dict(),
        )

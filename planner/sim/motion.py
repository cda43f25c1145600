"""Collision-free arm motion: OMPL's RRT-Connect in joint space, straight segments for
approach and retreat, every edge validated at a fixed joint-space resolution."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

Config = tuple[float, ...]
# A validity check returns the names of the bodies in collision (empty when the state is free).
Checker = Callable[[Config], Sequence[tuple[str, float]]]

ou.setLogLevel(ou.LOG_NONE)


@dataclass
class CollisionTally:
    """Which bodies made states invalid, how often, and how deep at most."""

    counts: Counter[str] = field(default_factory=Counter)
    depth: dict[str, float] = field(default_factory=dict)

    def add(self, hits: Sequence[tuple[str, float]]) -> None:
        for name in {n for n, _ in hits}:
            self.counts[name] += 1
        for name, depth in hits:
            self.depth[name] = max(self.depth.get(name, 0.0), depth)

    def ranked(self) -> list[tuple[str, int, float]]:
        """(body, count, max depth), the body most often in collision first."""
        return sorted(
            ((n, c, self.depth[n]) for n, c in self.counts.items()),
            key=lambda t: (-t[1], -t[2], t[0]),
        )


def interpolate(a: Config, b: Config, resolution: float) -> list[Config]:
    """States from a (excluded) to b (included), no joint moving more than `resolution`."""
    steps = max(1, math.ceil(max(abs(y - x) for x, y in zip(a, b, strict=True)) / resolution))
    return [
        tuple(x + (y - x) * k / steps for x, y in zip(a, b, strict=True))
        for k in range(1, steps + 1)
    ]


def check_segment(
    a: Config, b: Config, valid: Checker, resolution: float, tally: CollisionTally
) -> bool:
    for q in interpolate(a, b, resolution):
        hits = valid(q)
        if hits:
            tally.add(hits)
            return False
    return True


def rrt_connect(
    start: Config,
    goal: Config,
    valid: Checker,
    *,
    low: Sequence[float],
    high: Sequence[float],
    seed: int,
    max_checks: int,
    timeout: float,
    resolution: float,
    tally: CollisionTally,
) -> tuple[list[Config] | None, int]:
    """An RRT-Connect path from start to goal (None when the planner runs out of budget), and
    the number of collision checks it spent.

    The budget is counted in collision checks, not seconds, so that a verdict does not depend
    on how busy the machine is; `timeout` is only a safety net. OMPL's random generator is
    reseeded before the planner and its sampler exist, so the same query with the same seed
    gives the same path."""
    ou.RNG.setSeed(seed)
    dim = len(start)
    space = ob.RealVectorStateSpace(dim)
    bounds = ob.RealVectorBounds(dim)
    for i in range(dim):
        bounds.setLow(i, low[i])
        bounds.setHigh(i, high[i])
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)

    checks = [0]

    def is_valid(state: ob.State) -> bool:
        checks[0] += 1
        hits = valid(tuple(state[i] for i in range(dim)))
        if hits:
            tally.add(hits)
            return False
        return True

    setup.setStateValidityChecker(is_valid)
    info = setup.getSpaceInformation()
    # Edge checks every `resolution` of Euclidean joint distance: no joint moves more between them.
    info.setStateValidityCheckingResolution(resolution / space.getMaximumExtent())
    a, b = space.allocState(), space.allocState()
    for i in range(dim):
        a[i], b[i] = start[i], goal[i]
    setup.setStartAndGoalStates(a, b)
    setup.setPlanner(og.RRTConnect(info))
    budget = ob.PlannerTerminationCondition(lambda: checks[0] >= max_checks)
    stop = ob.plannerOrTerminationCondition(budget, ob.timedPlannerTerminationCondition(timeout))
    solved = setup.solve(stop)
    if not setup.haveExactSolutionPath() or not bool(solved):
        return None, checks[0]
    path = setup.getSolutionPath()
    states = [tuple(path.getState(k)[i] for i in range(dim)) for k in range(path.getStateCount())]
    return states, checks[0]

"""CPU core lists as Linux writes them (`1`, `1-3`, `0,2-3`): which cores a service runs on.

The embedded service of `cpkb plan` and `cpkb bench` shares a machine with its planners. A nice
value (`Settings.surrogate.nice`) only lowers the fits' priority: they still get a share of a
planner's core whenever they land on it, and evict its caches. Kept to the cores the planners
leave, the fits never stand between a planner and its next rollout.
"""

from __future__ import annotations

import os


def parse_cpu_list(text: str) -> frozenset[int]:
    """`0,2-3` -> {0, 2, 3}; a ValueError that names the part it cannot read."""
    cores: set[int] = set()
    for part in (p.strip() for p in text.split(",")):
        first, dash, last = part.partition("-")
        try:
            low, high = int(first), int(last) if dash else int(first)
        except ValueError:
            raise ValueError(f"{part!r} is not a core number or a range like 1-3") from None
        if low < 0 or high < low:
            raise ValueError(f"{part!r} is not a range of core numbers")
        cores.update(range(low, high + 1))
    return frozenset(cores)


def format_cpu_list(cores: frozenset[int] | set[int]) -> str:
    """{0, 2, 3} -> `0,2-3`."""
    ranges: list[list[int]] = []
    for core in sorted(cores):
        if ranges and core == ranges[-1][1] + 1:
            ranges[-1][1] = core
        else:
            ranges.append([core, core])
    return ",".join(str(a) if a == b else f"{a}-{b}" for a, b in ranges)


def spare_cores(taken: int) -> frozenset[int] | None:
    """The cores this process may run on beyond the first `taken` of them, or None where there
    are none to spare or the platform cannot pin a process (then the service shares them)."""
    if taken < 1 or not hasattr(os, "sched_getaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    return frozenset(allowed[taken:]) if len(allowed) > taken else None


def pin_process(cores: frozenset[int]) -> None:
    """Run this process, and every thread and child it starts from now on, on `cores`."""
    os.sched_setaffinity(0, cores)

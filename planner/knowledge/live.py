"""Other planners' points, taken in while this planner runs (live sharing).

A planner's local models change with the service's fits, and a fit lands seconds after the
points that call for it: later than most runs last. So the session polls, every few rollouts
and in the background, `POST /v1/kbs/{kb}/points/since` for the points other runs stored of the
types this run watches (its active types, and the types of graphs prematch found absent), and
folds them into its models as it does its own points. A watched absent type that comes back with
points was created by another planner meanwhile: the session activates it at once.

The other planners' feasible points are also kept apart (`PeerHints`), a few per type, as
candidates for this planner's MPF maximisation: a fresh point changes its model only within a
short reach (`surrogate.predictors.RecentPoints`), which the maximiser's raw samples rarely land in,
so without them a binding another planner has just found stays unseen here until a fit has
taken it in, and with several planners on one service the fits lag.

The cursor starts at the highest point id when the feed starts: what was stored before is in the
models this planner fetches. On PostgreSQL a point whose transaction commits after one with a
higher id was read is skipped here (it reaches this planner with the next fit).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

from contract.models import Constraint, LivePoint, PointsSinceOut, Value
from planner.knowledge.polls import PollSchedule

PollFn = Callable[[list[str], int | None], PointsSinceOut]
MAX_PAGES = 8  # pages one poll reads before it hands over what it has


class LiveFeed:
    def __init__(
        self,
        poll: PollFn,
        *,
        every_rollouts: int = 1,
        idle_max: int = 1,
        background: bool = True,
    ) -> None:
        self._poll = poll
        self.schedule = PollSchedule(every_rollouts, idle_max)
        self._cursor: int | None = None
        self._executor = (
            ThreadPoolExecutor(1, thread_name_prefix="cpkb-live") if background else None
        )
        self._in_flight: Future[tuple[int, list[LivePoint]]] | None = None
        self._watching = False  # the poll in flight asked for types (not the cursor alone)
        self.polls = 0
        self.points = 0

    @property
    def cursor(self) -> int | None:
        return self._cursor

    def start(self) -> None:
        """Take the cursor now (no points: what is stored already is in the models to fetch)."""
        if self._cursor is None and self._in_flight is None:
            self._submit([], None)

    def tick(self, rollout: int, type_ids: list[str]) -> list[LivePoint]:
        """The points a finished poll brought, and a new poll of `type_ids` if one is due."""
        points = self._land()
        if self._cursor is None:
            self.start()
            return points
        if self._in_flight is not None:
            return points
        if type_ids and self.schedule.due(rollout):
            self.schedule.polled(rollout)
            self._submit(type_ids, self._cursor)
            points += self._land()
        return points

    def close(self) -> None:
        """Stop polling (a poll under way is waited for, its points dropped)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        self._in_flight = None

    def _submit(self, type_ids: list[str], after: int | None) -> None:
        self.polls += 1
        self._watching = bool(type_ids)
        job = _Poll(self._poll, type_ids, after)
        if self._executor is None:
            done: Future[tuple[int, list[LivePoint]]] = Future()
            done.set_result(job())
            self._in_flight = done
        else:
            self._in_flight = self._executor.submit(job)

    def _land(self) -> list[LivePoint]:
        """The answer of a finished poll (its error, if it failed, is raised here)."""
        poll = self._in_flight
        if poll is None or not poll.done():
            return []
        self._in_flight = None
        cursor, points = poll.result()
        self._cursor = cursor if self._cursor is None else max(self._cursor, cursor)
        self.points += len(points)
        if self._watching:
            self.schedule.answered(bool(points))
        return points


class _Poll:
    """One poll: the pages after `after`, read up to `MAX_PAGES` (it reads nothing of the
    feed's state when it runs, so it can run in the background)."""

    def __init__(self, poll: PollFn, type_ids: list[str], after: int | None) -> None:
        self._poll, self._type_ids, self._after = poll, list(type_ids), after

    def __call__(self) -> tuple[int, list[LivePoint]]:
        answer = self._poll(self._type_ids, self._after)
        points = list(answer.points)
        for _ in range(MAX_PAGES - 1):
            if not answer.more:
                break
            answer = self._poll(self._type_ids, answer.cursor)
            points += answer.points
        return answer.cursor, points


class PeerHints:
    """The newest `per_type` feasible points of each type that other planners stored, as
    candidates (hints) for the MPF maximisation of a request that binds the type, preferred
    among its near-best candidates."""

    def __init__(self, per_type: int, limit: int) -> None:
        self.per_type = per_type
        self.limit = limit
        self._points: dict[str, list[tuple[int, str | None, dict[str, Value]]]] = {}
        self.used = 0  # hints handed to suggestions

    def add(self, point: LivePoint) -> None:
        """Keep a feasible point; its chain is its run's."""
        if not point.feasible or self.per_type <= 0:
            return
        kept = self._points.setdefault(point.type_id, [])
        kept.append((point.point_id, point.run, dict(point.x)))
        kept.sort(key=lambda item: item[0])
        del kept[: -self.per_type]

    def for_request(
        self, constraints: list[Constraint], free: set[str]
    ) -> tuple[list[dict[str, Value]], int]:
        """The kept points in the request's free variables, through each constraint binding
        their type, and how many of them, the first, to prefer (all). First come, per other
        run, its points merged (each variable at its newest value), so that the chain of
        decisions a run last passed (its binding, once it has one) is one candidate rather than
        scattered parts; the whole chains (the run passed every constraint of the request, and
        the chain gives every free variable) lead. At most `limit`, the newest first."""
        parts: list[tuple[int, str | None, dict[str, Value]]] = []
        passed: dict[str | None, set[str]] = {}
        for constraint in constraints:
            bind = constraint.bind
            for point_id, run, x in self._points.get(constraint.type_id, ()):
                passed.setdefault(run, set()).add(constraint.type_id)
                hint = {bind[k]: v for k, v in x.items() if bind.get(k) in free}
                if hint:
                    parts.append((point_id, run, hint))
        parts.sort(key=lambda part: part[0])
        merged: dict[str | None, dict[str, Value]] = {}
        for _, run, hint in parts:
            merged.setdefault(run, {}).update(hint)
        wanted = {c.type_id for c in constraints}
        runs = list(dict.fromkeys(run for _, run, _ in reversed(parts)))
        whole = [merged[r] for r in runs if passed[r] >= wanted and set(merged[r]) >= free]
        hints: list[dict[str, Value]] = []
        for hint in whole:
            if hint not in hints:
                hints.append(hint)
        for hint in [*(merged[r] for r in runs), *(h for *_, h in reversed(parts))]:
            if hint not in hints:
                hints.append(hint)
        hints = hints[: self.limit]
        self.used += len(hints)
        return hints, len(hints)

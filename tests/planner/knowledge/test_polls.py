"""When a background poll is due: at its pace, spaced out while answers come back empty."""

from __future__ import annotations

import pytest

from planner.knowledge.polls import PollSchedule


def _polls(schedule: PollSchedule, rollouts: range, answers=lambda r: False) -> list[int]:
    polled = []
    for rollout in rollouts:
        if schedule.due(rollout):
            schedule.polled(rollout)
            polled.append(rollout)
            schedule.answered(answers(rollout))
    return polled


def test_without_an_idle_limit_every_rollout_polls() -> None:
    assert _polls(PollSchedule(1), range(1, 11)) == list(range(1, 11))
    assert _polls(PollSchedule(3), range(1, 11)) == [1, 4, 7, 10]


def test_empty_answers_double_the_gap_up_to_the_limit() -> None:
    assert _polls(PollSchedule(1, idle_max=8), range(1, 40)) == [1, 3, 7, 15, 23, 31, 39]


def test_an_answer_with_something_restores_the_pace() -> None:
    schedule = PollSchedule(1, idle_max=8)
    polled = _polls(schedule, range(1, 40), answers=lambda r: r == 15)
    assert polled == [1, 3, 7, 15, 16, 18, 22, 30, 38]


def test_a_limit_below_the_pace_is_the_pace() -> None:
    schedule = PollSchedule(4, idle_max=2)
    assert schedule.idle_max == 4 and _polls(schedule, range(1, 14)) == [1, 5, 9, 13]


def test_a_pace_below_one_rollout_is_refused() -> None:
    with pytest.raises(ValueError, match="1 rollout"):
        PollSchedule(0)

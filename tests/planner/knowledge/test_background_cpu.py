"""A run records the CPU time its process's other threads took during the search: the poster,
the polls and the model refreshes hold the GIL while they run, so the search waits for them."""

from __future__ import annotations

from planner.run import run_plan


def test_a_guided_run_counts_its_background_threads_and_a_plain_one_has_none(live_kb):
    common = dict(kb_url=live_kb.url, kb=live_kb.name, max_rollouts=30, stop_at_first=False)
    guided = run_plan("analytic:deskP", "cp-bo", 3, **common)
    plain = run_plan("analytic:deskP", "quasi-random", 3, max_rollouts=30, stop_at_first=False)
    assert guided.knowledge.points_posted > 0
    assert guided.background_cpu_s > 0.0
    assert guided.to_json()["background_cpu_s"] == guided.background_cpu_s
    assert plain.background_cpu_s < 0.05

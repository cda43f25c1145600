"""CP-BO against the quasi-random baseline on the analytic desk, with a real service.

deskP (same shelf, other start; 30 rollouts, as the paper's predecessors) first stocks a fresh
knowledge base; once its surrogates are fitted, desk with cp-bo starts from deskP's shelf types
and needs fewer rollouts on average than desk with quasi-random over the same seeds.
"""

from __future__ import annotations

import statistics
import time
import uuid

import pytest

from client import CpkbClient
from planner.run import run_plan

SEEDS = range(3)


def wait_for_fits(client: CpkbClient, kb: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        states = [client.get_type(kb, t.type_id).surrogate for t in client.list_types(kb)]
        if all(s is not None and s.status in ("ready", "prior") for s in states):
            return
        time.sleep(0.2)
    pytest.fail(f"the surrogates of {kb} were not fitted within {timeout} s")


@pytest.mark.slow
def test_cp_bo_with_deskP_knowledge_needs_fewer_rollouts_than_quasi_random(kb_service):
    guided, baseline = [], []
    with CpkbClient(kb_service) as client:
        for seed in SEEDS:
            kb = f"cpbo-{uuid.uuid4().hex[:8]}"
            common = {"kb_url": kb_service, "kb": kb}
            learn = run_plan(
                "analytic:deskP",
                "cp-bo",
                100 + seed,
                max_rollouts=30,
                stop_at_first=False,
                **common,
            )
            assert learn.points_posted > 30
            wait_for_fits(client, kb)
            result = run_plan("analytic:desk", "cp-bo", seed, **common)
            assert result.solved and result.types_activated >= 1 and result.suggestions >= 1
            guided.append(result.rollouts)
            baseline.append(run_plan("analytic:desk", "quasi-random", seed).rollouts)
    assert statistics.mean(guided) < statistics.mean(baseline), (guided, baseline)

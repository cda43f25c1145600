"""Binding lists other runs of the same task found, followed once each (`FoundBindings`)."""

from __future__ import annotations

from wait_support import wait_until

from client import CpkbClient
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.knowledge.found import FoundBindings
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers.cp_bo import CpBoSampler

FOUND = {"#dir1": "front", "#pose12": [0.61, 0.32, 0.5]}


def _session(client: CpkbClient, kb: str, task: str = "desk", **config) -> KnowledgeSession:
    return KnowledgeSession(
        client, kb, analytic_world(task), background=False, config=KnowledgeConfig(**config)
    )


def test_a_binding_found_before_or_during_a_run_is_handed_out_once(live_kb) -> None:
    with CpkbClient(live_kb.url) as client:
        a = _session(client, live_kb.name)
        a.add_found(FOUND, rollout=3)
        b, other_task = _session(client, live_kb.name), _session(client, live_kb.name, "deskP")
        off = _session(client, live_kb.name, follow_found=False)
        for session in (b, other_task, off):
            session.prematch()
        assert b.next_chain() == FOUND and b.next_chain() is None
        assert other_task.next_chain() is None and off.next_chain() is None

        later = {**FOUND, "#dir1": "left"}
        a.add_found(later, rollout=9)
        b.add_found({**FOUND, "#dir1": "top"}, rollout=4)  # its own: never handed back
        rollouts = iter(range(1, 10**6))
        seen: list = []
        wait_until(
            lambda: b.on_rollout_end(next(rollouts)) or seen.append(b.next_chain()) or seen[-1],
            what="B reading A's binding stored while B runs",
        )
        assert seen[-1] == later and b.stats.found_followed == 2
        for session in (a, b, other_task, off):
            session.close()
            assert session.stats.kb_errors == 0


def test_a_task_run_again_follows_the_binding_found_before(live_kb) -> None:
    with CpkbClient(live_kb.url) as client:
        rollouts = []
        for seed in (1, 2):
            session = _session(client, live_kb.name)
            session.prematch()
            search = PWUCT(
                analytic_world("desk"), CpBoSampler(session), seed=seed, observer=session
            )
            result = search.run(2000)
            assert result.solved and result.bindings is not None
            session.add_found(result.bindings, result.rollouts)
            session.close()
            rollouts.append(result.rollouts)
    assert rollouts[0] > 1 and rollouts[1] == 1, rollouts


def test_an_unreachable_service_is_an_event_not_an_error_of_the_search() -> None:
    events: list[str] = []
    with CpkbClient("http://127.0.0.1:9", retries=0, timeout=2.0) as client:
        found = FoundBindings(
            client,
            "default",
            task="desk",
            skeleton=analytic_world("desk").skeleton,
            run="r",
            live=True,
            background=False,
            on_error=events.append,
        )
        found.start()
        found.tick(1)
        found.store(FOUND, rollout=1)
        found.close()
    assert found.next() is None
    assert len(events) == 3 and all(e.startswith("found bindings:") for e in events)

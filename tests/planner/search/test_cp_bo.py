"""CP-BO against the quasi-random baseline on the analytic desk, with a real service.

deskP (same shelf, other start; 30 rollouts, as the paper's predecessors) first stocks a fresh
knowledge base; once its surrogates are fitted, desk with cp-bo starts from deskP's shelf types
and needs fewer rollouts in the typical run (the median) than desk with quasi-random over the
same seeds.
"""

from __future__ import annotations

import statistics
import uuid

import pytest
from wait_support import wait_until

from client import CpkbClient
from planner.run import run_plan

SEEDS = range(10)


def wait_for_fits(client: CpkbClient, kb: str) -> None:
    def fitted() -> bool:
        states = [client.get_type(kb, t.type_id).surrogate for t in client.list_types(kb)]
        return all(s is not None and s.status in ("ready", "prior") for s in states)

    wait_until(fitted, interval=0.2, what=f"the fits of the surrogates of {kb}")


def stocked_desk_session(client: CpkbClient, kb: str):
    """The analytic desk and a prematched session on `kb`, after 40 quasi-random rollouts of
    desk have stocked it and its fits have landed."""
    from planner.knowledge import KnowledgeSession
    from planner.search import PWUCT
    from planner.search.analytic import analytic_world
    from planner.search.samplers.quasi_random import QuasiRandomSampler

    world = analytic_world("desk")
    stock = KnowledgeSession(client, kb, world, background=False)
    PWUCT(world, QuasiRandomSampler(), seed=0, observer=stock).run(40, stop_at_first=False)
    stock.close()
    wait_for_fits(client, kb)
    session = KnowledgeSession(client, kb, world, background=False)
    session.prematch()
    return world, session


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
            assert learn.knowledge.points_posted > 30
            wait_for_fits(client, kb)
            result = run_plan("analytic:desk", "cp-bo", seed, **common)
            assert (
                result.solved
                and result.knowledge.types_activated >= 1
                and result.knowledge.suggestions >= 1
            )
            guided.append(result.rollouts)
            baseline.append(run_plan("analytic:desk", "quasi-random", seed).rollouts)
    # The median: a guided run's count depends on when the service's fits land (a few runs
    # of ten go long either way), the typical run does not.
    assert statistics.median(guided) < statistics.median(baseline), (guided, baseline)


@pytest.mark.slow
def test_a_node_expands_from_one_batch_and_asks_again_when_it_is_used_up(live_kb):
    """Four expansions of one shelf node cost one suggestion; the fifth asks again. The values
    are distinct and inside the domain; a look at the best untried value takes it from the
    node's batch without using it up."""
    import numpy as np

    from planner.config import CpBoConfig
    from planner.search.samplers.base import Proposal, SampleContext
    from planner.search.samplers.cp_bo import CpBoSampler

    batch, max_age = CpBoConfig().batch, CpBoConfig().outlook_max_age

    with CpkbClient(live_kb.url) as client:
        world, session = stocked_desk_session(client, live_kb.name)
        sampler = CpBoSampler(session)
        pose = world.skeleton.decisions[1]
        siblings: list = []
        rng = np.random.default_rng(0)
        for expansion in range(batch + 1):
            ctx = SampleContext(pose, {"#dir1": "front"}, tuple(siblings), (), (), 1, 1, rng)
            proposal = sampler.propose(ctx)
            assert isinstance(proposal, Proposal) and 0.0 <= proposal.p_feasible <= 1.0
            assert proposal.value not in siblings and all(0 <= v <= 1 for v in proposal.value)
            siblings.append(proposal.value)
            assert session.stats.suggestions == (1 if expansion < batch else 2)
        grasp = world.skeleton.decisions[0]
        ctx = SampleContext(grasp, {}, ("front",), (), (), 0, 1, rng)
        untried = sampler.propose_untried(ctx)
        assert untried is not None and untried.value != "front"
        assert sampler.propose_untried(ctx) == untried == sampler.propose(ctx)
        assert session.stats.suggestions == 3
        later = SampleContext(grasp, {}, ("front",), (), (), 0, 1 + max_age + 1, rng)
        sampler.propose_untried(later)
        assert session.stats.suggestions == 4  # an old batch is asked for anew
        session.close()


@pytest.mark.slow
def test_an_outlook_younger_than_its_own_age_limit_is_read_without_asking(live_kb):
    """With `outlook_max_age` above `batch_max_age`, a look at an aged batch reads its best as
    it stands; taking a value from that batch asks anew, and so does a look past the limit."""
    import numpy as np

    from planner.config import CpBoConfig
    from planner.search.samplers.base import SampleContext
    from planner.search.samplers.cp_bo import CpBoSampler

    config = CpBoConfig(batch_max_age=8, outlook_max_age=32)
    with CpkbClient(live_kb.url) as client:
        world, session = stocked_desk_session(client, live_kb.name)
        sampler = CpBoSampler(session, config)
        grasp = world.skeleton.decisions[0]
        rng = np.random.default_rng(0)

        def at(rollout: int) -> SampleContext:
            return SampleContext(grasp, {}, ("front",), (), (), 0, rollout, rng)

        first = sampler.propose_untried(at(1))
        assert first is not None and session.stats.suggestions == 1
        assert sampler.propose_untried(at(1 + 20)) == first
        assert session.stats.suggestions == 1
        sampler.propose(at(1 + 20))
        assert session.stats.suggestions == 2
        sampler.propose_untried(at(1 + 20 + 33))
        assert session.stats.suggestions == 3
        session.close()


@pytest.mark.slow
def test_a_fresh_child_takes_its_first_value_from_the_parents_continuation(live_kb):
    """The grasp's suggestion looks ahead to the placement: the placement node under a
    suggested grasp expands first with the placement that answer chose, for no request; its
    next expansion asks. A child under a grasp the answer did not give has no continuation."""
    import numpy as np

    from planner.search.samplers.base import Proposal, SampleContext
    from planner.search.samplers.cp_bo import CpBoSampler

    with CpkbClient(live_kb.url) as client:
        world, session = stocked_desk_session(client, live_kb.name)
        sampler = CpBoSampler(session)
        grasp, pose = world.skeleton.decisions
        rng = np.random.default_rng(0)
        assert pose.var in {
            v for c in session.constraints_at(grasp.var, {}) for v in c.bind.values()
        }
        answered: list[dict] = []
        asked = session.suggest

        def recording(*args, **kwargs):
            answer = asked(*args, **kwargs)
            answered.extend(point.x for point in answer.batch or [answer])
            return answer

        session.suggest = recording
        chosen = sampler.propose(SampleContext(grasp, {}, (), (), (), 0, 1, rng))
        assert isinstance(chosen, Proposal) and session.stats.suggestions == 1
        grasp_batch = list(answered)
        path = {grasp.var: chosen.value}
        first = sampler.propose(SampleContext(pose, path, (), (), (), 1, 1, rng))
        assert session.stats.suggestions == 1
        assert first.value == next(x[pose.var] for x in grasp_batch if x[grasp.var] == chosen.value)
        second = sampler.propose(SampleContext(pose, path, (first.value,), (), (), 1, 2, rng))
        assert session.stats.suggestions == 2 and second.value != first.value
        other = next(
            c for c in grasp.domain.choices if c not in {x[grasp.var] for x in grasp_batch}
        )
        sampler.propose(SampleContext(pose, {grasp.var: other}, (), (), (), 1, 2, rng))
        assert session.stats.suggestions == 3
        session.close()


class _ScriptedKnowledge:
    """The session's side of the sampler, scripted: which types are active at a node, and an
    answer of `n` grasps (each with a placement) per request."""

    def __init__(self, skeleton) -> None:
        from planner.knowledge.session import KnowledgeStats

        self.skeleton = skeleton
        self.stats = KnowledgeStats()
        self.active: list = []
        self.batches: list[int] = []

    def constraints_at(self, var, path):
        return [c for c in self.active if var in c.bind.values() or not path]

    def suggest(self, var, path, siblings, constraints, seed, *, n=1):
        from contract.models import SuggestedPoint, SuggestOut

        self.stats.suggestions += 1
        self.batches.append(n)
        if not hasattr(var.domain, "choices"):  # a placement: points along the diagonal
            xs = [{var.var: [0.1 * (i + 1)] * 3} for i in range(n)]
        else:
            left = [c for c in var.domain.choices if c not in siblings][:n]
            xs = [{var.var: c, "#pose12": [0.5] * 3} for c in left]
        points = [SuggestedPoint(x=x, mpf=0.5, p_feasible={}) for x in xs]
        return SuggestOut(x=points[0].x, mpf=0.5, p_feasible={}, batch=points)


def test_a_batch_is_asked_anew_for_a_type_on_a_later_decision_it_looks_ahead_to():
    """A type met below the grasp, on the placement alone, voids the grasp's batch: the grasp
    is chosen for a feasible continuation (keeping the batch cost regrasp and pack transfer a
    quarter more rollouts, `benchmarks/results/paper7R`); an unchanged set keeps it."""
    import numpy as np

    from contract.models import Constraint
    from planner.search.analytic import analytic_world
    from planner.search.samplers.base import SampleContext
    from planner.search.samplers.cp_bo import CpBoSampler

    grasp = analytic_world("desk").skeleton.decisions[0]
    knowledge = _ScriptedKnowledge(analytic_world("desk").skeleton)
    knowledge.active = [Constraint(type_id="both", bind={"#dir": "#dir1", "#pose": "#pose12"})]
    sampler = CpBoSampler(knowledge)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    tried: list = []

    def expand() -> None:
        ctx = SampleContext(grasp, {}, tuple(tried), (), (), 0, 1, rng)
        tried.append(sampler.propose(ctx).value)

    expand()
    expand()
    assert knowledge.stats.suggestions == 1
    knowledge.active.append(Constraint(type_id="placement", bind={"#pose": "#pose12"}))
    expand()
    assert knowledge.stats.suggestions == 2
    assert len(set(tried)) == 3


def test_the_paper_preset_asks_for_one_point_per_expansion_and_keeps_no_continuation():
    """cp-bo-paper's sampler: every expansion is one suggestion of one point, and a placement
    under a suggested grasp asks for itself rather than taking the grasp answer's placement."""
    import numpy as np

    from contract.models import Constraint
    from planner.config import method_config
    from planner.search.analytic import analytic_world
    from planner.search.samplers.base import SampleContext
    from planner.search.samplers.cp_bo import CpBoSampler

    grasp, pose = analytic_world("desk").skeleton.decisions
    knowledge = _ScriptedKnowledge(analytic_world("desk").skeleton)
    knowledge.active = [Constraint(type_id="both", bind={"#dir": "#dir1", "#pose": "#pose12"})]
    sampler = CpBoSampler(knowledge, method_config("cp-bo-paper").cp_bo)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    first = sampler.propose(SampleContext(grasp, {}, (), (), (), 0, 1, rng)).value
    sampler.propose(SampleContext(grasp, {}, (first,), (), (), 0, 1, rng))
    assert knowledge.batches == [1, 1]
    sampler.propose(SampleContext(pose, {grasp.var: first}, (), (), (), 1, 1, rng))
    assert knowledge.stats.suggestions == 3
    extended = CpBoSampler(knowledge)  # type: ignore[arg-type]
    chosen = extended.propose(SampleContext(grasp, {}, (), (), (), 0, 2, rng)).value
    extended.propose(SampleContext(pose, {grasp.var: chosen}, (), (), (), 1, 2, rng))
    assert knowledge.batches == [1, 1, 1, 4]  # the placement came from the continuation


@pytest.mark.slow
def test_cp_bo_paper_switches_every_extension_off_in_a_run(live_kb, monkeypatch):
    """On a knowledge base stocked by deskP, cp-bo prematches, looks ahead, asks for batches and
    opens untried values by their outlook; cp-bo-paper does none of that, still activates the
    stored types when it meets their failures, and records its configuration."""
    from planner.knowledge import KnowledgeSession
    from planner.search.samplers.cp_bo import CpBoSampler

    common = {"kb_url": live_kb.url, "kb": live_kb.name}
    run_plan("analytic:deskP", "cp-bo", 100, max_rollouts=30, stop_at_first=False, **common)
    with CpkbClient(live_kb.url) as client:
        wait_for_fits(client, live_kb.name)
    seen: dict[str, list] = {"n": [], "ahead": [], "untried": []}
    suggest, untried = KnowledgeSession.suggest, CpBoSampler.propose_untried

    def spy_suggest(self, var, path, siblings, constraints, seed, *, n=1):
        seen["n"].append(n)
        bound = {v for c in constraints for v in c.bind.values()}
        seen["ahead"].append(bool(bound - set(path) - {var.var}))
        return suggest(self, var, path, siblings, constraints, seed, n=n)

    def spy_untried(self, ctx):
        seen["untried"].append(ctx.var.var)
        return untried(self, ctx)

    monkeypatch.setattr(KnowledgeSession, "suggest", spy_suggest)
    monkeypatch.setattr(CpBoSampler, "propose_untried", spy_untried)

    def run(method: str):
        for part in seen.values():
            part.clear()
        result = run_plan(
            "analytic:desk", method, 3, max_rollouts=60, stop_at_first=False, **common
        )
        return result, {k: list(v) for k, v in seen.items()}

    extended, used = run("cp-bo")
    assert extended.knowledge.types_prematched >= 1
    assert 4 in used["n"] and any(used["ahead"]) and used["untried"]
    paper, used = run("cp-bo-paper")
    assert paper.knowledge.types_prematched == 0 and paper.knowledge.types_activated >= 1
    assert used["n"] and set(used["n"]) == {1} and not any(used["ahead"]) and not used["untried"]
    assert paper.config["cp_bo"] == {
        "batch": 1,
        "batch_max_age": extended.config["cp_bo"]["batch_max_age"],
        "outlook_max_age": extended.config["cp_bo"]["outlook_max_age"],  # no outlook is read
        "lookahead": False,
        "continuations": False,
        "prematch": False,
    }
    search = paper.config["search"]
    assert not (search["outlook_widening"] or search["outlook_selection"])
    assert not (search["hopeless_widening"] or search["restart_redraws"])
    assert paper.config["knowledge"]["movable_names"]  # the paper's graphs name their bodies
    assert extended.config["knowledge"]["periodic_headings"]
    assert not paper.config["knowledge"]["periodic_headings"]  # a heading is a plain column


@pytest.mark.slow
def test_deterministic_runs_of_one_seed_on_fresh_knowledge_bases_agree(kb_service):
    """With every refit waited for, deskP then desk with cp-bo take the same course twice.

    A short deskP stock: each of its rollouts waits for a refit, and what it leaves unlearnt
    makes desk ask the knowledge base more, so more of the course is compared."""
    from planner.config import PlanConfig

    config = PlanConfig().with_overrides({"knowledge.deterministic": True})

    def chain() -> list[tuple]:
        common = {"kb_url": kb_service, "kb": f"det-{uuid.uuid4().hex[:8]}", "config": config}
        learn = run_plan(
            "analytic:deskP", "cp-bo", 7, max_rollouts=15, stop_at_first=False, **common
        )
        target = run_plan("analytic:desk", "cp-bo", 7, max_rollouts=300, **common)
        assert target.knowledge.kb_errors == 0 and target.knowledge.suggestions >= 1, target.notes
        assert "fit" in target.knowledge.kb_parts
        return [
            (
                r.rollouts,
                r.bindings,
                r.knowledge.points_posted,
                r.knowledge.suggestions,
                r.knowledge.types_active,
            )
            for r in (learn, target)
        ]

    assert chain() == chain()

"""MPF in the planner's process from model snapshots: the refresh policy over models held in
memory (`surrogate.sources.InMemoryModels`, sent through the service's snapshot form), and
against a real service where HTTP matters."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from recorded_support import recorded_models
from threadpoolctl import threadpool_info, threadpool_limits

from client import CpkbClient
from contract.models import SuggestIn
from planner.config import KnowledgeConfig
from planner.knowledge import KnowledgeSession
from planner.knowledge.local import LocalSurrogates, fetch_from, stated_prior
from planner.search import PWUCT
from planner.search.analytic import analytic_world
from planner.search.samplers.quasi_random import QuasiRandomSampler
from surrogate.config import OptimizerConfig
from surrogate.domains import space_from_json
from surrogate.encoding import SpaceEncoder
from surrogate.predictors import PriorPredictor, RecentPoints, VGPPredictor
from surrogate.sources import InMemoryModels

FIXTURE = Path(__file__).parents[2] / "surrogate" / "fixtures" / "suggest_requests.json"
RECORDED = json.loads(FIXTURE.read_text())
OPTIMIZER = OptimizerConfig(mpf_margin=0.1, mpf_margin_abs=0.025)  # the service's defaults


def _memory() -> InMemoryModels:
    return recorded_models()


def _grasp_request() -> SuggestIn:
    """A recorded grasp request: #dir1 with the placement after it looked ahead (n = 4)."""
    return SuggestIn.model_validate(next(r for r in RECORDED["requests"] if r.get("lookahead")))


def _stock(live_kb, task: str = "deskP", rollouts: int = 40) -> None:
    """Points of `task` in the knowledge base, and every type's fit landed (none queued: a fit
    landing between two calls would change the model under a comparison)."""
    with CpkbClient(live_kb.url) as client:
        world = analytic_world(task)
        session = KnowledgeSession(client, live_kb.name, world, background=False)
        PWUCT(world, QuasiRandomSampler(), seed=0, observer=session).run(
            rollouts, stop_at_first=False
        )
        session.close()
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            types = [
                client.get_type(live_kb.name, t.type_id) for t in client.list_types(live_kb.name)
            ]
            settled = [
                t.surrogate is not None
                and t.surrogate.n_fitted == t.n_points
                and t.surrogate.status not in ("fitting", "queued")
                for t in types
            ]
            if all(settled):
                return
            time.sleep(0.2)
        raise AssertionError("fits did not land in 120 s")


def test_a_planner_that_suggests_runs_its_blas_on_one_thread():
    """Its matrix products are too small for a second thread, which a loaded machine makes the
    first one wait for; the limit stays (a planner suggests again and again)."""
    with threadpool_limits(limits=2, user_api="blas"):
        LocalSurrogates(fetch_from(_memory(), OPTIMIZER), background=False)
        blas = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
        assert blas and set(blas) == {1}


@pytest.mark.parametrize("counts", [0.0, 2.0])
def test_own_points_weigh_in_before_the_next_fetch(counts):
    """A failure of this planner lowers its model where it failed at once. Nearest-point prior:
    the next suggestion goes elsewhere. Counted (the grasp type here holds two points, one
    feasible at the grasp suggested): one success and one failure rate the grasp 1/2, as an
    untried one, and the next suggestion sees that value."""
    request = _grasp_request()
    local = LocalSurrogates(fetch_from(_memory(), OPTIMIZER), background=False, prior_counts=counts)
    first = local.suggest(request, rollout=0, stored=0)
    type_id = min(first.p_feasible, key=first.p_feasible.get)
    constraint = next(c for c in request.constraints if c.type_id == type_id)
    x = {label: first.x[var] for label, var in constraint.bind.items()}
    model = local._models[type_id]
    z = SpaceEncoder(model.space).encode_points([x])
    before = float(model.model().proba(z)[0])
    local.note(type_id, x, feasible=False, batch=1)
    after = float(model.model().proba(z)[0])
    again = local.suggest(request, rollout=1, stored=0)
    assert after < before - 0.1
    assert local.fetches == 1  # weighed in without asking for the model again
    if counts:
        assert after == pytest.approx(0.5, abs=1e-3)
        assert again.mpf <= after + 1e-9
    else:
        assert again.x != first.x


@pytest.mark.parametrize("counts", [0.0, 2.0])
def test_points_weighed_in_one_by_one_predict_as_all_at_once(counts):
    """A model keeps the points since its fetch encoded as they come (`_Model._since`): after
    this planner's and another's points taken one at a time, with suggestions between them,
    it predicts exactly as a planner that took them all before asking."""
    request = _grasp_request()

    def planner() -> LocalSurrogates:
        fetch = fetch_from(_memory(), OPTIMIZER)
        return LocalSurrogates(fetch, background=False, prior_counts=counts)

    stepwise, at_once = planner(), planner()
    first = stepwise.suggest(request, rollout=0, stored=0)
    at_once.suggest(request, rollout=0, stored=0)
    constraint = request.constraints[0]
    type_id = constraint.type_id
    xs = [
        {label: point.x[var] for label, var in constraint.bind.items()}
        for point in [first, *first.batch]
    ]

    def take(local: LocalSurrogates, i: int, x: dict) -> None:
        if i % 3 == 2:
            local.learn(type_id, point_id=10_000 + i, x=x, feasible=False)
        else:
            local.note(type_id, x, feasible=i % 3 == 0, batch=1)

    for i, x in enumerate(xs):
        take(stepwise, i, x)
        stepwise.suggest(request, rollout=i + 1, stored=0)
    for i, x in enumerate(xs):
        take(at_once, i, x)
    z = SpaceEncoder(stepwise._models[type_id].space).encode_points(xs)
    np.testing.assert_array_equal(
        stepwise._models[type_id].model().proba(z),
        at_once._models[type_id].model().proba(z),
    )


@pytest.mark.parametrize("counts", [0.0, 2.0])
def test_a_stated_prior_counts_this_planners_failures_only_when_asked(counts):
    """`knowledge.prior_counts`: a fetched stated prior takes this planner's own points since
    as more of its points, so a place that failed again is rated lower each time; off, the
    nearest-point form stops falling after the first of this planner's failures there."""
    memory = _memory()
    space = {"#pose": {"kind": "continuous", "low": [0.0, 0.0], "high": [1.0, 1.0]}}
    memory.add("failing", space_from_json(space), [({"#pose": [0.2, 0.2]}, False)])
    local = LocalSurrogates(fetch_from(memory, OPTIMIZER), background=False, prior_counts=counts)
    local._apply(local._fetch_now(["failing"]), ["failing"], 0, 0, 0)
    model = local._models["failing"]
    there = SpaceEncoder(model.space).encode_points([{"#pose": [0.2, 0.2]}])
    once = float(model.model().proba(there)[0])
    for _ in range(2):
        local.note("failing", {"#pose": [0.2, 0.2]}, feasible=False, batch=1)
    thrice = float(model.model().proba(there)[0])
    for _ in range(3):
        local.note("failing", {"#pose": [0.2, 0.2]}, feasible=False, batch=1)
    six = float(model.model().proba(there)[0])
    if counts:
        assert once == pytest.approx(1 / 3, abs=1e-6) and thrice == pytest.approx(1 / 5, abs=1e-6)
        assert six == pytest.approx(1 / 8, abs=1e-6)
    else:
        assert once == pytest.approx(0.05, abs=1e-6) and six == pytest.approx(thrice, abs=1e-9)


def test_the_stated_prior_under_served_recent_points_counts_them_as_its_own():
    """A prior the service serves with points since (`RecentPoints` on a prior) is one prior
    with all those points; a fit is no stated prior."""
    none, here = np.zeros((0, 2)), np.array([[0.3, 0.3]])
    served = RecentPoints(PriorPredictor(none, here).counted(2.0), here, np.vstack([here, here]))
    prior = stated_prior(served)
    assert prior is not None and len(prior.feasible) == 1 and len(prior.infeasible) == 3
    assert prior.proba(here)[0] == pytest.approx(2 / 6, abs=1e-9)
    fit = VGPPredictor(here, np.ones(2), 1.0, 0.0, np.zeros(1), np.zeros((1, 1)))
    assert stated_prior(RecentPoints(fit, here, none)) is None


@pytest.mark.parametrize("walls", [False, True])
def test_the_planners_spread_rule_holds_over_the_services_settings(walls):
    """`knowledge.spread_walls` decides the local maximiser's spread, whatever optimiser
    settings the service sends with its snapshots."""
    local = LocalSurrogates(fetch_from(_memory(), OPTIMIZER), background=False, spread_walls=walls)
    local.suggest(_grasp_request(), rollout=0, stored=0)
    assert local._config.spread_walls is walls
    assert local._config.mpf_margin == OPTIMIZER.mpf_margin


def test_served_points_stay_pending_until_a_point_answers_them():
    """As in the service: a batch's unused points, and other nodes' recent suggestions, push
    the next suggestion away."""
    request = _grasp_request()
    local = LocalSurrogates(fetch_from(_memory(), OPTIMIZER), background=False)
    first = local.suggest(request, rollout=0, stored=0)
    served = len(first.batch)
    assert first.n_pending == 0 and served > 1 and local._pending.count("local") == served
    again = local.suggest(request, rollout=0, stored=0)
    assert again.n_pending == served
    assert local._pending.count("local") == served + len(again.batch)
    constraint = next(c for c in request.constraints if set(c.bind.values()) == set(request.space))
    answered = {label: first.x[var] for label, var in constraint.bind.items()}
    local.note(constraint.type_id, answered, feasible=True, batch=1)
    # Entries hold the node's variable only (#dir1): the point answers every one of its grasp.
    same = sum(p.x["#dir1"] == first.x["#dir1"] for p in first.batch + again.batch)
    assert same >= 1
    assert local._pending.count("local") == served + len(again.batch) - same


def test_a_refresh_runs_in_the_background_and_lands_at_the_next_suggestion():
    """A type in use is fetched anew without holding up the suggestion: while the fetch is
    under way the model in hand (with this planner's own points) answers; the next suggestion
    after it finished takes the new snapshot, keeping only the own points posted since."""
    request = _grasp_request()
    fetch_models = fetch_from(_memory(), OPTIMIZER)
    release = threading.Event()
    calls: list[dict] = []

    def fetch(ids, known):
        calls.append(dict(known))
        if len(calls) > 1:
            assert release.wait(120)
        return fetch_models(ids, {})

    local = LocalSurrogates(fetch)
    first = local.suggest(request, rollout=0, stored=0)
    type_id = next(iter(first.p_feasible))
    constraint = next(c for c in request.constraints if c.type_id == type_id)
    x = {label: first.x[var] for label, var in constraint.bind.items()}
    local.note(type_id, x, feasible=False, batch=1)
    old = local._models[type_id]
    local.suggest(request, rollout=3, stored=1)
    assert local.fetches == 2
    assert local._models[type_id] is old and local._in_flight is not None
    assert not local._in_flight.answer.done()  # held until `release`: it did not wait
    local.note(type_id, x, feasible=True, batch=2)
    release.set()
    local._in_flight.answer.result(timeout=120)
    local.suggest(request, rollout=4, stored=2)
    new = local._models[type_id]
    local.close()
    assert new is not old and calls[1][type_id] == old.version
    assert [batch for batch, _, _ in new.own] == [2]
    assert local.fetches == 2


@pytest.mark.slow
def test_a_planner_answers_its_own_suggestions(live_kb):
    from planner.run import run_plan

    common = {"kb_url": live_kb.url, "kb": live_kb.name}
    run_plan("analytic:deskP", "cp-bo", 3, max_rollouts=30, stop_at_first=False, **common)
    result = run_plan("analytic:desk", "cp-bo", 3, **common)
    assert result.solved and result.knowledge.kb_errors == 0
    assert result.knowledge.suggestions > 0
    assert result.knowledge.local_suggestions == result.knowledge.suggestions
    assert 0 < result.knowledge.model_fetches <= result.knowledge.suggestions


@pytest.mark.slow
def test_a_failed_local_suggestion_falls_back_for_that_call_only(live_kb):
    """A fetch that fails (a passing network error, a service without snapshots): the service
    answers that call, the problem is counted, and the next call is answered here again."""
    _stock(live_kb)

    class FlakyService(CpkbClient):
        failures = 1

        def models(self, *args, **kwargs):
            if FlakyService.failures:
                FlakyService.failures -= 1
                raise RuntimeError("connection reset")
            return super().models(*args, **kwargs)

    world = analytic_world("desk")
    with FlakyService(live_kb.url) as client:
        session = KnowledgeSession(client, live_kb.name, world)
        session.prematch()
        grasp = world.skeleton.decisions[0]
        constraints = session.constraints_at("#dir1", {})
        first = session.suggest(grasp, {}, [], constraints, seed=1)
        second = session.suggest(grasp, {}, [], constraints, seed=2)
        session.close()
    assert first is not None and first.method == "mpf", session.stats.events
    assert second is not None and second.method == "mpf-local"
    assert session.stats.suggestions == 2 and session.stats.local_suggestions == 1
    assert session.stats.events == {
        "local suggestion failed, the service answers instead: connection reset": 1
    }


@pytest.mark.slow
def test_a_type_this_planner_creates_guides_at_once_as_the_service_would(live_kb):
    """A failure of a new type is taken up by the planner's own models at once (no wait for
    its first point to be stored, no fetch): the stated prior on the planner's own points,
    which is what the service serves for it once stored (the nearest-point form: counting the
    points is the planner's choice, `knowledge.prior_counts`)."""
    _stock(live_kb)
    with CpkbClient(live_kb.url) as client:
        world = analytic_world("desk")
        config = KnowledgeConfig(prior_counts=0.0)
        session = KnowledgeSession(client, live_kb.name, world, background=False, config=config)
        session.prematch()
        grasp = world.skeleton.decisions[0]
        assert session.suggest(grasp, {}, [], session.constraints_at("#dir1", {}), seed=0)
        known = set(session.active)
        bindings = {"#dir1": "back"}  # blocked at desk's start pose: not a deskP constraint
        session.on_transition(0, bindings, world.transition(0, bindings, None), rollout=1)
        session.on_rollout_end(1)
        new = [a for key, a in session.active.items() if key not in known]
        assert len(new) == 1 and new[0].stored_with == 0  # nothing to wait for
        model = session.guidance.local._models[new[0].type_id]
        assert not model.fetched
        xs = [{"#dir": choice} for choice in grasp.domain.choices]
        mine = model.model().proba(SpaceEncoder(model.space).encode_points(xs))
        served = client.predict(live_kb.name, new[0].type_id, xs)
        assert list(mine) == pytest.approx(served, rel=1e-6, abs=1e-9) and min(served) < 0.5
        session.close()


def test_a_cp_bo_planner_loads_without_torch() -> None:
    """A planner scores served snapshots with NumPy predictors, so starting one (every built-in
    sampler registered, the cp-bo sampler built) does not pay for importing torch, gpytorch or
    the fitting libraries; only the service fits."""
    probe = (
        "import sys\n"
        "from planner.search import samplers\n"
        "import planner.run\n"
        "from planner.knowledge.local import LocalSurrogates\n"
        "samplers.methods()\n"
        "heavy = ('torch', 'gpytorch', 'imblearn', 'sklearn')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=300
    )
    assert result.stdout.strip() == "[]"

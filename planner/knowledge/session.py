"""The knowledge base in the loop of one binding search.

The session observes every transition the search runs and answers the sampler's questions. It is
three parts, built here in one place from the configuration: matching (`TypeMatcher`: which
types bind which checks), guidance (`Guidance`: suggestions from local models and hints, found
bindings) and sharing (`Sharing`: posting points, the live feed, the waits of deterministic
mode). Only `match` and `suggest` block the search, and their time is `kb_s`.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Sequence

from contract.models import Constraint, PointIn, Source, SuggestOut, Value
from planner.config import KnowledgeConfig
from planner.failures import Encodings, FailureGraph
from planner.knowledge.client import KnowledgeClient
from planner.knowledge.found import FoundBindings
from planner.knowledge.guidance import Guidance, suggest_request
from planner.knowledge.live import LiveFeed, PeerHints
from planner.knowledge.local import LocalSurrogates
from planner.knowledge.matching import Activation, Observed, TypeMatcher
from planner.knowledge.poster import PointPoster
from planner.knowledge.sharing import Sharing
from planner.knowledge.stats import KnowledgeStats
from planner.skeleton import DecisionVar
from planner.world import BindingWorld, TransitionOutcome


def _never() -> float:
    """A clock that stands still: pending suggestions leave only when a point answers them."""
    return 0.0


class KnowledgeSession:
    def __init__(
        self,
        client: KnowledgeClient,
        kb: str,
        world: BindingWorld,
        *,
        run: str | None = None,
        worker: str | None = None,
        background: bool = True,
        lookahead: bool = True,
        local: bool = True,
        config: KnowledgeConfig | None = None,
    ) -> None:
        """`local`: maximise MPF in this process from the service's model snapshots (else the
        service answers every suggestion); `lookahead`: `CpBoConfig.lookahead`."""
        self.config = config if config is not None else KnowledgeConfig()
        self.kb = kb
        self.world = world
        self.skeleton = world.skeleton
        self.lookahead = lookahead
        self.run = run or uuid.uuid4().hex[:16]
        self.worker = worker
        self.stats = KnowledgeStats()
        self.sharing, self.guidance = _parts(
            client,
            kb,
            world,
            self.run,
            self.config,
            self.stats,
            background and not self.config.deterministic,
            local,
        )
        self.matcher = TypeMatcher(
            client,
            kb,
            self.skeleton,
            _encodings(world, self.config),
            self.stats,
            self._stored_with,
            match_chunk=self.config.match_chunk,
        )
        self._domains = {d.var: d.domain for d in self.skeleton.decisions}
        self._observed: list[Observed] = []
        self._rollout = 0

    # -- observing the search -----------------------------------------------------------------

    def prematch(self, *, found: bool = True) -> None:
        """Activate the known types among every graph this task could produce; with `found`,
        also read the binding lists earlier runs found (`read_found`)."""
        self.stats.types_prematched = self.matcher.prematch(self.world.culprit_candidates)
        self.sharing.start()
        if found:
            self.read_found()

    def read_found(self) -> None:
        """Read the binding lists earlier runs of this task found: the tree follows them first."""
        if self.guidance.found is not None:
            self.guidance.found.start()

    def on_transition(
        self, index: int, bindings: dict[str, Value], outcome: TransitionOutcome, rollout: int
    ) -> None:
        self._rollout = rollout
        self._observed += self.matcher.observe(index, bindings, outcome)

    def on_rollout_end(self, rollout: int) -> None:
        """Activate the types of failures met for the first time, then post this rollout's
        points in one batch (in the background)."""
        self.matcher.match(only_existing=False)
        source = Source(task=self.world.name, run=self.run, rollout=rollout, worker=self.worker)
        points = [
            PointIn(
                graph=fg.graph,
                x=x,
                feasible=feasible,
                source=source,
                key=f"{self.run}:{rollout}:{i}",
            )
            for i, (_, fg, x, feasible) in enumerate(self._observed)
        ]
        batch = self.sharing.post(points)
        active = self.matcher.active
        for key, _, x, feasible in self._observed:
            if key in active:
                self.guidance.note(active[key].type_id, x, feasible, batch)
        self._take_live(rollout)
        if self.guidance.found is not None:
            self.guidance.found.tick(rollout)
        if self.config.deterministic:
            met = {active[k].type_id for k, *_ in self._observed if k in active}
            self.sharing.wait_for_fits(met)
        self._observed = []

    def _take_live(self, rollout: int) -> None:
        """Weigh in the other planners' points a poll brought, and activate the types they
        created among the graphs prematch found absent."""
        points = self.sharing.poll(rollout, self.matcher.watched())
        created: dict[str, int] = {}
        for point in points:
            active = point.type_id in self.matcher.types
            self.guidance.learn(point, active)
            if not active:
                created[point.type_id] = created.get(point.type_id, 0) + 1
        if created:
            self.stats.live_types += self.matcher.born(created)

    def _stored_with(self, type_id: str, graph: FailureGraph) -> int:
        """The poster batch after which the service holds a type this run creates with its
        next batch; 0 if this process's models take it up at once."""
        batch = self.sharing.poster.submitted + 1
        space = {
            n.label: n.domain
            for n in graph.graph.nodes
            if n.role == "decision" and n.domain is not None  # a decision's is never None
        }
        return 0 if self.guidance.adopt(type_id, space, batch) else batch

    # -- guiding the search -------------------------------------------------------------------

    def next_chain(self) -> dict[str, Value] | None:
        """A binding list another run of this task found, to follow now (each once)."""
        return self.guidance.next_chain()

    def add_found(self, bindings: dict[str, Value], rollout: int) -> None:
        """Store the binding list this run found, for the other runs of its task."""
        self.guidance.store_found(bindings, rollout)

    def constraints_at(self, var: str, path: dict[str, Value]) -> list[Constraint]:
        """The active types that constrain this decision (`TypeMatcher.constraints_at`). A type
        met in this run exists once its first point is stored: that batch is waited for, so
        that when a type starts guiding does not depend on timing (unless this process's own
        models took it up at once: `LocalSurrogates.adopt`)."""
        return self.matcher.constraints_at(
            var,
            path,
            lookahead=self.lookahead,
            ready=lambda activation: self.sharing.wait_stored(activation.stored_with),
        )

    def suggest(
        self,
        var: DecisionVar,
        path: dict[str, Value],
        siblings: Sequence[Value],
        constraints: list[Constraint],
        seed: int,
        *,
        n: int = 1,
    ) -> SuggestOut | None:
        """The MPF suggestion (with `n > 1`, a batch of spread points), or None if it could not
        be had."""
        request = suggest_request(var, path, siblings, constraints, self._domains, seed, n)
        return self.guidance.suggest(
            request, rollout=self._rollout, stored=self.sharing.poster.done
        )

    def close(self) -> None:
        """Post what is left and wait for the background threads. This comes after the search
        has its binding, so its time is kept apart (`kb_parts["close"]`), not in `kb_s`."""
        started = time.perf_counter()
        if self._observed:
            self.on_rollout_end(self._rollout)
        self.sharing.close()
        self.guidance.close()
        self.stats.kb_parts["close"] = time.perf_counter() - started

    @property
    def points_posted(self) -> int:
        return self.sharing.poster.posted

    @property
    def active(self) -> dict[tuple[int, int, str | None], Activation]:
        return self.matcher.active


def _encodings(world: BindingWorld, config: KnowledgeConfig) -> Encodings:
    return Encodings(
        world.geometry,
        square_grasps=config.square_grasps,
        grasp_symmetry=config.grasp_symmetry,
        relative_pairs=config.relative_pairs,
        periodic_headings=config.periodic_headings,
        movable_names=config.movable_names,
    )


def _parts(
    client: KnowledgeClient,
    kb: str,
    world: BindingWorld,
    run: str,
    config: KnowledgeConfig,
    stats: KnowledgeStats,
    background: bool,
    local: bool,
) -> tuple[Sharing, Guidance]:
    """Sharing and guidance as the configuration has them: local models where the planner
    maximises MPF itself; the live feed and hints with `live_points` (not in deterministic
    mode, whose runs must not depend on what others post meanwhile) and local models; found
    bindings with `follow_found`."""
    poster = PointPoster(
        lambda pts: client.post_points(kb, pts),
        background=background,
        linger_s=config.post_linger_ms / 1000.0,
    )
    models = (
        LocalSurrogates(
            lambda ids, known: client.models(kb, ids, known),
            background=background,
            refresh_rollouts=config.refresh_rollouts,
            prior_counts=config.prior_counts,
            spread_walls=config.spread_walls,
            # A lifetime in wall time would make a run's course depend on its waits.
            pending_clock=_never if config.deterministic else time.monotonic,
        )
        if local
        else None
    )
    live = config.live_points and not config.deterministic
    feed = (
        LiveFeed(
            lambda ids, after: client.points_since(kb, ids, after, exclude_run=run),
            every_rollouts=config.live_every_rollouts,
            idle_max=config.live_idle_max,
            background=background,
        )
        if live and models is not None
        else None
    )
    hints = (
        PeerHints(config.live_hints, config.live_hints_limit)
        if feed is not None and config.live_hints > 0
        else None
    )
    found = (
        FoundBindings(
            client,
            kb,
            task=world.name,
            skeleton=world.skeleton,
            run=run,
            live=live,
            every_rollouts=config.live_every_rollouts,
            idle_max=config.live_idle_max,
            background=background,
            on_error=stats.event,
        )
        if config.follow_found
        else None
    )
    sharing = Sharing(client, kb, stats, poster=poster, live=feed, fit_wait_s=config.fit_wait_s)
    return sharing, Guidance(client, kb, stats, local=models, hints=hints, found=found)

"""A categorical choice that failed inconclusively (IK restarts, a sampling motion planner) is
tried again where no continuous decision lies above it; a proven failure never is."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from contract.models import CategoricalDomain, ContinuousDomain, Value
from planner.config import SearchConfig
from planner.search import PWUCT
from planner.search.samplers.quasi_random import QuasiRandomSampler
from planner.search.tree import ChildNode, DecisionNode, add_child, close, widens
from planner.skeleton import DecisionVar, Layer, OperatorCall, Skeleton
from planner.world import CheckResult, TransitionOutcome, WorldGeometry

CONFIG = SearchConfig()
CALL = OperatorCall("Inv-kin", ("body", "pose0", "#dir1"))
PASS = TransitionOutcome((CheckResult(CALL, True),))
PROVEN = TransitionOutcome((CheckResult(CALL, False, "collides"),))
UNLUCKY = TransitionOutcome((CheckResult(CALL, False, "no IK solution", conclusive=False),))
GRASP = DecisionVar(
    "#dir1", "#dir", CategoricalDomain(choices=["a", "b"]), OperatorCall("Sample", (), ("#dir1",))
)
PLACE = DecisionVar(
    "#pose12",
    "#pose",
    ContinuousDomain(low=[0.0], high=[1.0]),
    OperatorCall("Sample", (), ("#pose12",)),
)


def grasp_node(retries: int) -> DecisionNode:
    return DecisionNode(0, GRASP, {}, None, retries=retries)


def tried(node: DecisionNode, value: str, outcome: TransitionOutcome) -> ChildNode:
    child = ChildNode(value, node, outcome)
    add_child(node, child)
    close(child)
    return child


def test_an_inconclusive_failure_is_retried_until_its_attempts_run_out():
    node = grasp_node(retries=2)
    tried(node, "a", PROVEN)
    tried(node, "b", UNLUCKY)
    assert node.all_tried and not node.exhausted and not node.closed
    assert widens(node, CONFIG.pw_k)  # every child closed: a retry at once
    assert node.retry_choice() == ("b", 1)
    tried(node, "b", UNLUCKY)
    assert node.retry_choice() == ("b", 2)
    tried(node, "b", UNLUCKY)
    assert node.retry_choice() is None and node.exhausted and node.closed and node.dead
    assert not widens(node, CONFIG.pw_k)


def test_a_proven_failure_or_a_passed_choice_is_never_retried():
    node = grasp_node(retries=3)
    tried(node, "a", PROVEN)
    passed = ChildNode("b", node, PASS)
    add_child(node, passed)
    assert node.retry_choice() is None and node.exhausted
    assert not widens(node, CONFIG.pw_k)


def test_without_retries_an_inconclusive_failure_closes_the_choice():
    node = grasp_node(retries=0)
    tried(node, "a", UNLUCKY)
    tried(node, "b", UNLUCKY)
    assert node.exhausted and node.closed


@dataclass
class UnluckyFirstIk:
    """A grasp-then-place world: grasp `b` is the only one that can pick, and its IK finds a
    solution only from the second attempt on; any placement then passes."""

    name: str = "unlucky"
    skeleton: Skeleton = field(
        default_factory=lambda: Skeleton(
            (
                Layer("decision", (), GRASP),
                Layer("transition", (CALL,)),
                Layer("decision", (), PLACE),
                Layer("transition", (CALL,)),
            )
        )
    )
    geometry: WorldGeometry = field(default_factory=WorldGeometry)
    attempts: list[tuple[int, Value, int]] = field(default_factory=list)

    def initial_state(self) -> object:
        return None

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        self.attempts.append((index, bindings["#dir1"], attempt))
        if index == 1:
            return PASS
        if bindings["#dir1"] == "a":
            return PROVEN
        return PASS if attempt >= 1 else UNLUCKY


def test_the_search_retries_the_only_grasp_that_can_pick_with_fresh_draws():
    world = UnluckyFirstIk()
    result = PWUCT(world, QuasiRandomSampler(), seed=0).run(50)
    assert result.solved and result.bindings is not None and result.bindings["#dir1"] == "b"
    assert (0, "b", 1) in world.attempts  # the retry told the world it was a second attempt


def test_with_retries_off_the_same_world_is_exhausted():
    world = UnluckyFirstIk()
    config = replace(CONFIG, inconclusive_retries=0)
    result = PWUCT(world, QuasiRandomSampler(), seed=0, config=config).run(50)
    assert not result.solved and result.rollouts == 2
    assert all(attempt == 0 for _, _, attempt in world.attempts)


def test_no_retries_below_a_continuous_decision():
    place_first = Skeleton(
        (
            Layer("decision", (), PLACE),
            Layer("transition", (CALL,)),
            Layer("decision", (), GRASP),
            Layer("transition", (CALL,)),
        )
    )

    @dataclass
    class PlaceThenGrasp(UnluckyFirstIk):
        skeleton: Skeleton = field(default_factory=lambda: place_first)

        def transition(self, index, bindings, state, *, attempt=0):  # type: ignore[override]
            self.attempts.append((index, bindings.get("#dir1"), attempt))
            return PASS if index == 0 else UNLUCKY

    world = PlaceThenGrasp()
    PWUCT(world, QuasiRandomSampler(), seed=0).run(30)
    assert all(attempt == 0 for _, _, attempt in world.attempts)

"""`PyBulletWorld`: a task's skeleton executed in PyBullet, behind the `BindingWorld` seam."""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, replace

from contract.models import CategoricalDomain, Value
from planner.sim.geometry import Pose
from planner.sim.grasps import Grasp
from planner.sim.motion import CollisionTally
from planner.sim.operators import OPERATORS, ArmConfig, Execution
from planner.sim.scene import Scene
from planner.skeleton import Skeleton
from planner.tasks import Task, build_skeleton
from planner.tasks.loader import HOME_CONFIG, PANDA_URDF
from planner.world import CheckResult, TransitionOutcome, WorldGeometry


@dataclass(frozen=True)
class SimState:
    """Everything needed to put the world back as it was after a transition: arm, fingers,
    body poses, the grasp held (if any) and the values produced so far (#config1, #traj01)."""

    arm: tuple[float, ...]
    fingers: float
    poses: tuple[tuple[str, Pose], ...]
    held: Grasp | None
    values: tuple[tuple[str, object], ...]


class PyBulletWorld:
    """One task in its own PyBullet client (`self.scene.client`); DIRECT unless `gui`."""

    def __init__(
        self,
        task: Task,
        *,
        seed: int,
        gui: bool = False,
        scene: Scene | None = None,
    ) -> None:
        """`scene`: another world's scene of the same bodies, to share one PyBullet client
        among the skeletons of one goal (`planner.goals`); its owner closes it."""
        self.task = task
        self.name = task.name
        self.seed = int(seed)
        self.skeleton: Skeleton = build_skeleton(task)
        self._owns_scene = scene is None
        self.scene = scene if scene is not None else Scene(task, gui=gui)
        self.pose_sources = {
            d.var: (d.producer.args[0], d.producer.args[1])
            for d in self.skeleton.decisions
            if d.kind == "#pose"
        }
        self._initial = SimState(
            arm=tuple(task.workspace.robot.home),
            fingers=self.scene.max_finger_opening,
            # Where the task puts them, not where a shared scene's last search left them.
            poses=self.scene.start_poses(),
            held=None,
            values=((HOME_CONFIG, ArmConfig(tuple(task.workspace.robot.home))),),
        )
        # Every name a check may report as a culprit, for pre-matching failure graphs.
        self.culprit_candidates: tuple[str, ...] = (
            *self.scene.static_names,
            *self.scene.movable_names,
            "robot",
        )
        self.geometry = WorldGeometry(
            body_sizes=tuple(
                (name, (float(sx), float(sy), float(sz)))
                for name in self.scene.movable_names
                for sx, sy, sz in [self.scene.sizes[name]]
            ),
            arm="" if task.workspace.robot.urdf == PANDA_URDF else task.workspace.robot.urdf,
        )
        self.restore(self._initial)

    @property
    def client(self) -> int:
        return self.scene.client

    def initial_state(self) -> SimState:
        return self._initial

    def restore(self, state: object) -> None:
        if not isinstance(state, SimState):
            raise TypeError(f"not a state of this world: {type(state).__name__}")
        for name, pose in state.poses:
            self.scene.set_pose(name, pose)
        self.scene.set_arm(state.arm)
        self.scene.set_fingers(state.fingers)

    def transition(
        self, index: int, bindings: Mapping[str, Value], state: object, *, attempt: int = 0
    ) -> TransitionOutcome:
        started = time.perf_counter()
        layers = self.skeleton.transitions
        if not 0 <= index < len(layers):
            raise IndexError(f"{self.name} has transition layers 0..{len(layers) - 1}, not {index}")
        self._check_bindings(index, bindings)
        self.restore(state)
        assert isinstance(state, SimState)
        ex = Execution(
            scene=self.scene,
            settings=self.task.settings,
            seed=self.seed,
            attempt=attempt,
            bindings=bindings,
            pose_sources=self.pose_sources,
            values=dict(state.values),
            arm=state.arm,
            held=state.held,
        )
        checks: list[CheckResult] = []
        for call in layers[index].calls:
            ex.tally = CollisionTally()
            call_start = time.perf_counter()
            result = OPERATORS[call.name](call, ex)
            seconds = {"seconds": time.perf_counter() - call_start}
            result = replace(result, detail={**result.detail, **seconds})
            checks.append(result)
            if not result.ok:
                return TransitionOutcome(tuple(checks), None, time.perf_counter() - started)
        new_state = SimState(
            arm=ex.arm,
            fingers=self.scene.fingers(),
            poses=tuple((n, self.scene.pose(n)) for n in self.scene.movable_names),
            held=ex.held,
            values=tuple(ex.values.items()),
        )
        return TransitionOutcome(tuple(checks), new_state, time.perf_counter() - started)

    def _check_bindings(self, index: int, bindings: Mapping[str, Value]) -> None:
        for d in self.skeleton.decisions[: index + 1]:
            if d.var not in bindings:
                raise KeyError(f"{self.name}: transition {index} needs a binding for {d.var}")
            value = bindings[d.var]
            choices = d.domain.choices if isinstance(d.domain, CategoricalDomain) else None
            if d.kind == "#dir" and choices is not None and value not in choices:
                raise ValueError(f"{d.var} must be one of {choices}, got {value!r}")
            if d.kind == "#pose" and (not isinstance(value, list | tuple) or len(value) != 3):
                raise ValueError(f"{d.var} must be 3 numbers in [0, 1], got {value!r}")

    def close(self) -> None:
        if self._owns_scene:
            self.scene.close()

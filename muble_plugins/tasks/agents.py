"""Built-in agents: the oracle (the task's plan, replanned after every primitive) and a random baseline."""
from __future__ import annotations

import copy
import dataclasses
import logging
import zlib
from dataclasses import dataclass

import numpy as np

from muble import ActionCall, ActionResult, Agent, Answer, Instruction, Observation, SceneGraph, Task, get_registry

from muble.core.observation import MEASURED_STIFFNESS
from muble.core.symbolic import ArmState

from muble_plugins.tasks.symbolic import APPROACH, GRASP, LIFT, LOWER, MOVE, RELEASE, SQUEEZE, WEIGH

log = logging.getLogger(__name__)


@dataclass
class OracleConfig:
    pass


class OracleAgent(Agent):
    """Solves any task that plans towards its goal (``Task.next_actions``), closed loop.

    After every primitive it asks the instruction's task (the registered task named by its ``template_id``, or
    the one it was built for) for the next primitives from the observed scene, with the weights and stiffnesses it
    measured so far (the scene's ``weight`` fields and ``extra["stiffness_measured"]``, which hold only what this
    agent measured, and the ``weigh`` and ``squeeze`` results), and takes the first; so a slipped grasp or a
    displaced object is simply planned around. The gripper's state comes from the scene's flags (``in_hand``,
    ``raised``, ``approached``, ``gripper_over``), which the symbolic and the physical world both report; a world
    without the hover flags has them filled in from the last primitive.

    After a failed primitive it starts that object's part of the plan over (the hover and grasp-pose flags
    forgotten) and retries differently: primitives that take an ``attempt`` get the number of failures so far on
    that target, so they start from their next-best grasp, place or hover pose.

    Privileged by definition: whatever the run's track and observation mode, it is given the program and the
    graph view, and its actions are put in the mode's form (pixel targets in ``image`` mode), so its success
    shows that each mode is solvable; it is never a contestant.
    """

    privileged = True

    def __init__(self, task: Task | None = None) -> None:
        self.task = task
        self.tasks: dict[str, Task] = {}
        self.measured: dict[int, float] = {}
        self.stiffness: dict[int, float] = {}  # N/m, from this agent's squeeze results
        self.answered = False
        self.last: ActionCall | None = None
        self.failures: dict[object, int] = {}  # failed primitives per target (object id, table part or None)

    def reset(self, instruction: Instruction, observation: Observation) -> None:
        self.measured = {}
        self.stiffness = {}
        self.answered = False
        self.last = None
        self.failures = {}

    def _task(self, instruction: Instruction) -> Task:
        if self.task is not None:
            return self.task
        if instruction.template_id not in self.tasks:
            self.tasks[instruction.template_id] = get_registry().create("task", instruction.template_id, {})
        return self.tasks[instruction.template_id]

    def _known(self, observation: Observation) -> Observation:
        """The observation with this agent's measurements and the gripper's hover state filled in."""
        scene = copy.deepcopy(observation.scene)
        fill_known(scene, self.measured, self.stiffness, self.last, observation.last_result)
        return dataclasses.replace(observation, scene=scene)

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        result = observation.last_result
        if self.last is not None and result is not None:
            if not result.success:
                key = self._target(self.last)
                self.failures[key] = self.failures.get(key, 0) + 1
                log.info("%s failed (%s); retrying differently", self.last, result.failure_reason)
            elif self.last.name in (WEIGH, SQUEEZE) and isinstance(result.measurement, (int, float)):
                held = ArmState.of(observation.scene).held
                if held is not None:
                    store = self.measured if self.last.name == WEIGH else self.stiffness
                    store[held] = float(result.measurement)
        step = self._task(instruction).next_actions(instruction, self._known(observation))
        if isinstance(step, Answer):
            if self.answered:
                return None
            self.answered = True
            return step
        self.last = self._retry(step[0]) if step else None
        return self.last

    @staticmethod
    def _target(action: ActionCall) -> object:
        return action.params.get("target")

    def _retry(self, action: ActionCall) -> ActionCall:
        """``action`` with ``attempt`` set to the failures on its target, where the primitive takes one."""
        attempt = min(self.failures.get(self._target(action), 0), RETRY_LIMIT)
        if attempt and "attempt" in primitive_params(action.name):
            return ActionCall(action.name, {**action.params, "attempt": attempt})
        return action


def fill_known(scene: SceneGraph, measured: dict[int, float], stiffness: dict[int, float],
               last: ActionCall | None, result: ActionResult | None) -> None:
    """Fill an agent's copy of the observed ``scene`` with what it knows: the weights and stiffnesses it measured,
    and the gripper's hover state. After a failed primitive (``result`` of ``last``) the hover and grasp-pose
    flags are cleared, so the plan starts over from hovering (a failed grasp or put-down leaves the hand where it
    should not stay); a world that reports no hover flags has them filled in from the last primitive. The oracle
    and the learned planner keep the same books, so the planner's labels fit."""
    for o in scene.objects:
        if o.weight is None and o.id in measured:
            o.weight = measured[o.id]
        if MEASURED_STIFFNESS not in o.extra and o.id in stiffness:
            o.extra[MEASURED_STIFFNESS] = stiffness[o.id]
    reported = any("gripper_over" in o.extra or "approached" in o.extra for o in scene.objects)
    if last is not None and result is not None and not result.success:
        for o in scene.objects:
            o.extra["approached"] = o.extra["gripper_over"] = False
    elif not reported and last is not None and result is not None:
        target = last.params.get("target")
        held = ArmState.of(scene).held
        for o in scene.objects:
            o.extra["gripper_over"] = last.name == MOVE and o.id == target
            o.extra["approached"] = last.name == APPROACH and held is None and o.id == target


RETRY_LIMIT = 16  # the highest ``attempt`` the built-in primitives take


def primitive_params(name: str) -> set[str]:
    """Names of the parameters the registered primitive ``name`` declares (empty if unknown)."""
    from muble.core.params import specs

    registry = get_registry()
    if name not in registry.names("primitive"):
        return set()
    return {p.name for p in specs(registry.get("primitive", name).record.factory.params)}


@dataclass
class RandomConfig:
    seed: int = 0
    stop_probability: float = 0.05  # chance per step of declaring the task done


class RandomAgent(Agent):
    """Uniformly random primitives on random objects: the floor every reasoner should beat."""

    def __init__(self, seed: int = 0, stop_probability: float = 0.05) -> None:
        self.seed = seed
        self.stop_probability = stop_probability
        self.rng = np.random.default_rng(seed)

    def reset(self, instruction: Instruction, observation: Observation) -> None:
        # Each episode its own stream, reproducible from (seed, split, scene index, template).
        episode = zlib.crc32(f"{instruction.split}/{instruction.image_index}/{instruction.template_id}".encode())
        self.rng = np.random.default_rng([self.seed, episode])

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        if self.rng.random() < self.stop_probability:
            return None
        ids = [o.id for o in observation.scene.objects]
        name = (MOVE, APPROACH, GRASP, LIFT, WEIGH, LOWER, RELEASE)[int(self.rng.integers(7))]
        if name in (MOVE, APPROACH, GRASP) and ids:
            return ActionCall(name, {"target": ids[int(self.rng.integers(len(ids)))]})
        if name in (MOVE, APPROACH, GRASP) and observation.images:
            # Image mode (no object ids): a random pixel of the latest image names the target.
            height, width = next(iter(observation.images.values())).rgb.shape[:2]
            return ActionCall(name, {"target": [int(self.rng.integers(width)), int(self.rng.integers(height))]})
        return ActionCall(name)

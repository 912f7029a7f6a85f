"""Built-in agents: the oracle (ground-truth program, replanned after every primitive) and a random baseline."""
from __future__ import annotations

import zlib

import logging
from dataclasses import dataclass

import numpy as np

from muble import ActionCall, Agent, Answer, Instruction, Observation, get_registry

from muble_plugins.tasks.planner import plan_next
from muble_plugins.tasks.symbolic import APPROACH, GRASP, LIFT, LOWER, MOVE, RELEASE, WEIGH, ArmState

log = logging.getLogger(__name__)


@dataclass
class OracleConfig:
    pass


class OracleAgent(Agent):
    """Executes the instruction's program with closed-loop replanning.

    After every primitive it reruns the program on the observed scene graph with the weights measured so far
    (from the scene's ``weight`` fields, which hold only what it measured, and from ``weigh`` results) and takes
    the first primitive of the new plan; so a slipped grasp or a displaced object is simply planned around. The
    gripper's state comes from the scene's flags (``in_hand``, ``raised``, ``approached``, ``gripper_over``),
    which the symbolic and the physical world both report.

    After a failed primitive it starts that object's part of the plan over (move, approach …, the hover and
    grasp-pose flags forgotten) and retries differently: primitives that take an ``attempt`` get the number of
    failures so far on that target, so they start from their next-best grasp, place or hover pose.
    """

    def __init__(self) -> None:
        self.measured: dict[int, float] = {}
        self.answered = False
        self.last: ActionCall | None = None
        self.failures: dict[object, int] = {}  # failed primitives per target (object id, table part or None)

    def reset(self, instruction: Instruction, observation: Observation) -> None:
        self.measured = {}
        self.answered = False
        self.last = None
        self.failures = {}

    def _arm(self, observation: Observation) -> ArmState:
        """The gripper state from the scene's flags; a world that reports no hover flags (``approached``,
        ``gripper_over``) has them filled in from what the last successful primitive did."""
        arm = ArmState.of(observation.scene)
        reported = any("gripper_over" in o.extra or "approached" in o.extra for o in observation.scene.objects)
        result, last = observation.last_result, self.last
        if last is not None and result is not None and not result.success:
            # Start over from hovering: a failed grasp or put-down leaves the hand where it should not stay.
            arm.approached = arm.over = None
            return arm
        if reported or last is None or result is None:
            return arm
        target = last.params.get("target")
        if last.name == MOVE and isinstance(target, int):
            arm.over = int(target)
        elif last.name == APPROACH and arm.held is None:
            arm.approached = int(target)
        return arm

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        scene = observation.scene
        result = observation.last_result
        weighed = self.last is not None and self.last.name == WEIGH
        if weighed and result is not None and result.success and isinstance(result.measurement, (int, float)):
            held = ArmState.of(scene).held
            if held is not None:
                self.measured[held] = float(result.measurement)
        if self.last is not None and result is not None and not result.success:
            key = self._target(self.last)
            self.failures[key] = self.failures.get(key, 0) + 1
            log.info("%s failed (%s); retrying differently", self.last, result.failure_reason)
        plan = plan_next(instruction.program, scene, self.measured, self._arm(observation))
        if plan.answer is not None:
            if self.answered:
                return None
            self.answered = True
            return plan.answer
        self.last = self._retry(plan.actions[0]) if plan.actions else None
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
        return ActionCall(name)

"""Built-in agents: the oracle (ground-truth program, replanned after every primitive) and a random baseline."""
from __future__ import annotations

import zlib

import logging
from dataclasses import dataclass

import numpy as np

from muble import ActionCall, Agent, Answer, Instruction, Observation

from muble_plugins.tasks.planner import plan_next
from muble_plugins.tasks.symbolic import APPROACH, GRASP, LIFT, LOWER, MOVE, RELEASE, WEIGH, ArmState

log = logging.getLogger(__name__)


@dataclass
class OracleConfig:
    pass


class OracleAgent(Agent):
    """Executes the instruction's program with closed-loop replanning.

    After every primitive it reruns the program on the observed scene graph with the weights measured so far
    (from the scene's ``weight`` fields and from ``weigh`` results) and takes the first primitive of the new
    plan; so a slipped grasp or a displaced object is simply planned around. The gripper's state comes from the
    scene's flags (``in_hand``, ``raised``, ``approached``, ``gripper_over``), which the symbolic and the
    physical world both report.
    """

    def __init__(self) -> None:
        self.measured: dict[int, float] = {}
        self.answered = False
        self.last: ActionCall | None = None

    def reset(self, instruction: Instruction, observation: Observation) -> None:
        self.measured = {}
        self.answered = False
        self.last = None

    def _arm(self, observation: Observation) -> ArmState:
        """The gripper state from the scene's flags; a world that reports no hover flags (``approached``,
        ``gripper_over``) has them filled in from what the last successful primitive did."""
        arm = ArmState.of(observation.scene)
        reported = any("gripper_over" in o.extra or "approached" in o.extra for o in observation.scene.objects)
        result, last = observation.last_result, self.last
        if reported or last is None or result is None or not result.success:
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
        plan = plan_next(instruction.program, scene, self.measured, self._arm(observation))
        if plan.answer is not None:
            if self.answered:
                return None
            self.answered = True
            return plan.answer
        self.last = plan.actions[0] if plan.actions else None
        return self.last


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

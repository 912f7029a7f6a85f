"""A primitive and a task of one's own: ``tap`` an object, and "Touch the red mug." judged from the episode.

Written against MuBlE's public API only: the primitive builds on the registered primitives, the task plans
through ``Task.next_actions`` (so the built-in oracle solves it) and judges the episode record (``Task.judge``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import muble
from muble import ActionCall, ActionResult, Answer, Instruction, Observation, Outcome, Param


class Tap(muble.PrimitiveAction):
    """Touch an object with the open hand: hover over it, come down into its grasp pose, rise again."""

    params = (Param("target", "object", required=True),)

    def execute(self, env) -> ActionResult:
        registry = muble.get_registry()
        target = int(self.arguments["target"])
        for name, params in (("move", {"target": target}), ("approach", {"target": target}),
                             ("lift", {"height": 0.08})):
            result = registry.create("primitive", name, params).execute(env)
            if not result.success:
                return ActionResult(False, failure_reason=f"tap: {name} failed ({result.failure_reason})")
        return ActionResult(True, info={"tapped": target})

    def symbolic_effect(self, scene) -> ActionResult:
        target = scene.object(int(self.arguments["target"]))
        target.extra["touched"] = True  # ground truth only: agents do not see unknown keys
        return ActionResult(True, info={"tapped": target.id})


@dataclass
class TouchConfig:
    pickupable_only: bool = True  # offer only objects the hand can close around


class Touch(muble.Task):
    """"Touch the <colour> <category>." for an object whose colour and category name it alone."""

    task_id = "touch"

    def __init__(self, config: TouchConfig | None = None):  # the registry's checked options, or the defaults
        self.pickupable_only = (config or TouchConfig()).pickupable_only

    def generate(self, scene, rng: np.random.Generator) -> list[Instruction]:
        names = [(o.colour, o.name) for o in scene.objects]
        unique = [o for o in scene.objects if names.count((o.colour, o.name)) == 1
                  and (o.pickupable or not self.pickupable_only)]
        found = []
        for k in rng.permutation(len(unique)):
            obj = unique[int(k)]
            # The step's input_value says which object in words an agent can match (its colour and category);
            # its output, the object's id, is ground truth that only the judge sees.
            program = [{"type": "scene", "input": None, "input_value": None, "output": scene.ids},
                       {"type": "touch", "input": [0], "input_value": [obj.colour, obj.name], "output": [obj.id]}]
            found.append(Instruction(f"Touch the {obj.colour} {obj.name}.", program, "touch", self.task_id,
                                     scene.image_filename, scene.image_index, scene.split))
        return found

    @staticmethod
    def target(instruction: Instruction) -> int:
        """The object to touch as recorded at generation (ground truth: for judging)."""
        return int(instruction.program[-1]["output"][0])

    @staticmethod
    def described(instruction: Instruction, scene) -> int:
        """The object the instruction describes, found in a scene by its visible colour and category."""
        colour, name = instruction.program[-1]["input_value"]
        (obj,) = [o for o in scene.objects if o.colour == colour and o.name == name]
        return obj.id

    def ground_truth(self, instruction: Instruction, scene) -> list[ActionCall]:
        return [ActionCall("tap", {"target": self.described(instruction, scene)})]

    def next_actions(self, instruction: Instruction, observation: Observation) -> list[ActionCall] | Answer:
        # Planned from what an agent may know: the instruction's words and the observed scene.
        target = self.described(instruction, observation.scene)
        done = observation.last_result is not None and observation.last_result.success \
            and observation.last_result.info.get("tapped") == target
        return [] if done else [ActionCall("tap", {"target": target})]

    def judge(self, instruction: Instruction, episode) -> Outcome:
        target = self.target(instruction)
        tapped = any(step.action.name == "tap" and step.action.params.get("target") == target
                     and step.result.success for step in episode.steps)
        return Outcome.SUCCESS if tapped else Outcome.SCENE_INCONSISTENCY

    def check(self, instruction: Instruction, scene, answer) -> Outcome:
        # Without the episode record only the symbolic world's mark can tell.
        touched = scene.object(self.target(instruction)).extra.get("touched")
        return Outcome.SUCCESS if touched else Outcome.SCENE_INCONSISTENCY

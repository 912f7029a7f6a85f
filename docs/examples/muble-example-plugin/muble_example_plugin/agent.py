"""An agent of one's own: ``greedy``, a rule-based reasoner for the program track in graph mode.

It reads the words of the program (the ``input_value`` of its attribute filters) to find its target among the
observed objects, then runs a fixed script of registered primitives:

- a program that ends in ``query_weight`` on one object ("How heavy is the bowl?"): grasp it, lift it, weigh it
  and answer ``[grams]``;
- one that ends in ``pick_up``: grasp the object and lift it; where a ``filter_weight`` chooses among several
  ("Lift the lightest of all cylindrical objects.") it weighs each candidate first and lifts the extreme.

Anything else (spatial filters, moves, stacks, several objects to measure; the language track, which gives no
program; any observation mode but graph, which gives no attribute words: ``reset`` tells it both) it does not
attempt: it stops. It does not retry: after a failed primitive it
stops too, and the episode is judged as it stands. It sees only what every agent is given, never ground truth.
"""
from __future__ import annotations

import logging
from collections.abc import Generator
from dataclasses import dataclass

import muble
from muble import ActionCall, ActionResult, Answer, Instruction, Observation, ObservationMode, Track

log = logging.getLogger(__name__)

# Program steps whose words name a visible attribute: step type -> scene object field.
ATTRIBUTE_FILTERS = {"filter_colour": "colour", "filter_material": "material", "filter_name": "name",
                     "filter_shape": "shape", "filter_size": "size"}
KNOWN_STEPS = {"scene", "filter_weight", "query_weight", "pick_up", *ATTRIBUTE_FILTERS}

Script = Generator[ActionCall | Answer, ActionResult | None, None]


@dataclass
class GreedyConfig:
    # Ranges are checked when the config is composed: a value the lift primitive would refuse is an error up front.
    lift_height: float = muble.bounded(0.15, ge=0.01, le=0.4)  # m the object is raised, as the lift primitive takes
    max_weighings: int = muble.bounded(5, ge=1)  # the most candidates weighed to choose the lightest or heaviest


class GreedyAgent(muble.Agent):
    """Scripted grasp, lift, weigh and answer for the single-object templates (see the module doc)."""

    def __init__(self, config: GreedyConfig | None = None):  # the registry's checked options, or the defaults
        self.config = config or GreedyConfig()
        self.script: Script | None = None
        self.last: ActionCall | Answer | None = None

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        attempted = track == Track.program and mode == ObservationMode.graph
        self.script = self._script(instruction.program, observation.scene) if attempted else None
        self.last = None

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        result = observation.last_result
        if self.script is None:
            return None
        if self.last is not None and result is not None and not result.success:
            log.info("%s failed (%s); stopping", self.last, result.failure_reason)
            self.script = None
            return None
        try:
            # The script gets the result of the primitive it chose last (a weigh's grams are its measurement).
            self.last = next(self.script) if self.last is None else self.script.send(result)
        except StopIteration:
            self.script = None
            return None
        return self.last

    def _script(self, program: list[dict], scene: muble.SceneGraph) -> Script:
        """The episode's decisions in order; each ``yield`` of a primitive gets back its result."""
        kinds = [step.get("type") for step in program]
        if not kinds or kinds[-1] not in ("query_weight", "pick_up") or not set(kinds) <= KNOWN_STEPS:
            return
        targets = [o.id for o in scene.objects]
        for step in program:
            if step["type"] in ATTRIBUTE_FILTERS:
                attribute = ATTRIBUTE_FILTERS[step["type"]]
                targets = [i for i in targets if getattr(scene.object(i), attribute) == step["input_value"]]
        superlative = next((s["input_value"] for s in program if s["type"] == "filter_weight"), None)
        if kinds[-1] == "query_weight" and len(targets) == 1:
            grams = yield from self._weigh(targets[0])
            yield Answer([grams])
        elif kinds[-1] == "pick_up" and len(targets) == 1:
            yield from self._hold_up(targets[0])
        elif kinds[-1] == "pick_up" and superlative and 1 < len(targets) <= self.config.max_weighings:
            weights = {}
            for k, target in enumerate(targets):
                if k:
                    yield ActionCall("lower")  # the one weighed before goes back down where it was
                weights[target] = yield from self._weigh(target)
            choice = (max if superlative == "heaviest" else min)(weights, key=weights.get)
            if choice != targets[-1]:
                yield ActionCall("lower")
                yield from self._hold_up(choice)

    def _hold_up(self, target: int) -> Script:
        yield ActionCall("move", {"target": target})  # the hand above it
        yield ActionCall("approach", {"target": target})  # down into its grasp pose
        yield ActionCall("close_gripper", {"target": target})
        yield ActionCall("lift", {"height": self.config.lift_height})

    def _weigh(self, target: int) -> Generator[ActionCall, ActionResult, float]:
        yield from self._hold_up(target)
        result = yield ActionCall("weigh")
        return float(result.measurement)

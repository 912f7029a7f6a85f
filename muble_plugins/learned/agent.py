"""``agent=learned_planner``: a trained planner network picks every primitive and its target.

Each step the agent books the last primitive's result (measured weights and stiffnesses, failures per target),
runs the program on the observed scene to find the current sub-goal, builds the token features
(``planner_features``) and takes the network's argmax primitive and target. After failures on a target it passes
``attempt`` to primitives that take one, so they start from their next-best grasp, place or hover pose (as the
oracle does). When the network says stop on a query program, the answer is the program's output on what was
measured. It is not privileged: it sees what its track and mode show.

``reset`` tells it its track and observation mode. On the language track (no program given) a trained
instruction parser (``agent.parser=PATH``) gives the program; in masks mode (no attribute words) a trained
attribute recogniser (``agent.recogniser=PATH``) names the objects. Image mode (no object ids) is not supported.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from muble import ActionCall, Agent, Answer, Instruction, Observation, ObservationMode, Track
from muble.core.errors import ConfigError
from muble.core.ranges import configured

from muble_plugins.common.books import RETRY_LIMIT, primitive_params
from muble_plugins.learned.config import LearnedPlannerConfig
from muble_plugins.learned.planner_features import Memory, decode, observe_features

ATTRIBUTES = ("name", "colour", "material", "shape", "size", "stackable", "stack_base", "pickupable")


def load_network(path: str | Path):
    """The planner network of a checkpoint (``ConfigError`` for a missing or wrong file)."""
    from muble_plugins.learned import checkpoint as ck

    payload = ck.load(path, "planner")
    from muble_plugins.learned.planner_net import PlannerNet

    model = payload.get("extra", {}).get("model")
    if not isinstance(model, dict):
        raise ConfigError(f"'{path}' holds no planner network description; train it again with "
                          "`muble train trainer=planner`")
    from muble_plugins.learned.planner_features import layout

    trained, here = payload.get("extra", {}).get("layout"), layout()
    if trained is not None and trained != here:  # checkpoints before the layout was recorded have the built-in one
        extra = sorted(set(trained["properties"]) ^ set(here["properties"]))
        raise ConfigError(f"'{path}' was trained with the hidden properties {trained['properties']}, and "
                          f"{here['properties']} are registered here (differing: {extra}); train it again with "
                          "`muble train trainer=planner` under the installed packages, or install the ones it was "
                          "trained with")
    net = PlannerNet(**model)
    try:
        net.load_state_dict(payload["state"]["model"])
    except (KeyError, RuntimeError) as e:
        raise ConfigError(f"'{path}' does not fit this planner network ({e}); train it again with "
                          "`muble train trainer=planner`") from e
    net.eval()
    return net


class LearnedPlannerAgent(Agent):
    """Primitives and targets from a trained planner (``muble train trainer=planner``).

    Built from a ``LearnedPlannerConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``LearnedPlannerAgent(checkpoint="runs/planner/planner.pt")``); ``network``, a planner network already in
    memory, stands in for the checkpoint's.
    """

    def __init__(self, config: LearnedPlannerConfig | None = None, *, network: Any = None, **options: Any) -> None:
        self.config = cfg = configured(LearnedPlannerConfig, config, options, owner="agent 'learned_planner'")
        self.checkpoint = cfg.checkpoint
        self.net = network if network is not None else load_network(cfg.checkpoint)
        self.parser_path, self.recogniser_path = cfg.parser, cfg.recogniser
        self._parser = self._recogniser = None
        self.memory = Memory()
        self.answered = False
        self.program: list[dict] | None = None
        self.recognised: dict[int, dict[str, Any]] = {}
        self.track, self.mode = Track.program, ObservationMode.graph

    # -- language track and masks mode ---------------------------------------------------------------------
    def _parse(self, instruction: Instruction) -> list[dict]:
        if self.track == Track.program:
            return instruction.program
        if self.parser_path is None:
            raise ConfigError("the language track gives no program: agent=learned_planner needs a trained parser, "
                              "agent.parser=PATH (muble train trainer=parser)")
        if self._parser is None:
            from muble_plugins.learned.parser import InstructionParser

            self._parser = InstructionParser.load(self.parser_path)
        return self._parser.parse(instruction.instruction)

    def _with_attributes(self, observation: Observation) -> Observation:
        if self.mode == ObservationMode.graph:
            return observation
        objects = observation.scene.objects
        if self.recogniser_path is None:
            raise ConfigError("masks mode gives no attribute words: agent=learned_planner needs a trained "
                              "recogniser, agent.recogniser=PATH (muble train trainer=recogniser)")
        if self._recogniser is None:
            from muble_plugins.learned.recogniser import AttributeRecogniser

            self._recogniser = AttributeRecogniser.load(self.recogniser_path)
        if any(o.id not in self.recognised for o in objects):
            found = self._recogniser.recognise(observation)
            for obj_id, words in found.items():
                self.recognised.setdefault(int(obj_id), dict(words))
        scene = dataclasses.replace(observation.scene, objects=[
            dataclasses.replace(o, **{k: v for k, v in self.recognised.get(o.id, {}).items() if k in ATTRIBUTES})
            for o in objects])
        return dataclasses.replace(observation, scene=scene)

    # -- acting ---------------------------------------------------------------------------------------------
    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        if mode == ObservationMode.image:
            raise ConfigError("agent=learned_planner needs object ids (graph or masks mode); image mode, where "
                              "objects are named by pixels, is not supported")
        self.track, self.mode = Track(track), ObservationMode(mode)
        self.memory = Memory()
        self.answered = False
        self.program = None
        self.recognised = {}

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        from muble_plugins.learned.planner_net import decide

        if self.program is None:
            self.program = self._parse(instruction)
        observation = self._with_attributes(observation)
        failed = self.memory.observe(observation)
        tokens, goal, scene = observe_features(self.memory, self.program, observation, failed)
        cls, pointer = decide(self.net, tokens)
        call = decode(cls, pointer, scene)
        if call is None:
            if goal.answer is not None and not self.answered:
                self.answered = True
                return Answer(list(goal.answer))
            return None
        call = self._retry(call)
        self.memory.last = call
        return call

    def _retry(self, call: ActionCall) -> ActionCall:
        """``call`` with ``attempt`` set to the failures on its target, where the primitive takes one."""
        attempt = min(self.memory.failures.get(call.params.get("target"), 0), RETRY_LIMIT)
        if attempt and "attempt" in primitive_params(call.name):
            return ActionCall(call.name, {**call.params, "attempt": attempt})
        return call

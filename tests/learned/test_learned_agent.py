"""``agent=learned_planner`` without a trained network's quality in question: what it needs on each track and in
each mode, how it retries, and how it answers queries (the network's decisions stubbed)."""
from __future__ import annotations

import dataclasses
import sys
import types

import pytest

pytest.importorskip("torch")

from muble import ActionCall, ActionResult, Answer, Observation, ObservationMode, Outcome, Track  # noqa: E402
from muble.core.errors import ConfigError  # noqa: E402
from muble.episode import run_episode  # noqa: E402
from muble.episode.modes import track_instruction  # noqa: E402

import muble_plugins.learned.planner_net as planner_net  # noqa: E402
from muble_plugins.agents.oracle import OracleAgent  # noqa: E402
from muble_plugins.common.success import check  # noqa: E402
from muble_plugins.common.symbolic import SymbolicWorld  # noqa: E402
from muble_plugins.learned.agent import LearnedPlannerAgent  # noqa: E402
from muble_plugins.learned.planner import instructions_for, scene_for  # noqa: E402
from muble_plugins.learned.planner_features import CLASSES, IGNORE, encode  # noqa: E402


def _episode(template: str):
    for index in range(50):
        scene = scene_for(5, index, True)
        for instruction in instructions_for(scene, 5, index, True):
            if instruction.template_id == template:
                return instruction, scene
    raise AssertionError(f"no {template} instruction in 50 scenes")


class _Stub:
    """Stands in for the network: the decisions ``choose(tokens)`` gives."""


@pytest.fixture
def oracle_network(monkeypatch):
    """A 'network' that decides what the oracle would, so the agent's own bookkeeping is what is tested."""
    state = {}

    def decide(net, tokens):
        return state["next"]

    monkeypatch.setattr(planner_net, "decide", decide)
    return state


def _play_with_oracle_decisions(state, instruction, scene, world=None, track="program"):
    """Play the learned agent where each decision is the oracle's on the same observation."""
    agent = LearnedPlannerAgent(network=_Stub())
    oracle = OracleAgent()
    original = agent.act

    def act(told, observation):
        decision = oracle.act(instruction_full, observation)
        state["next"] = encode(decision, observation.scene)
        return original(told, observation)

    instruction_full = track_instruction(instruction, "program")
    agent.act = act
    agent_reset = agent.reset

    def reset(told, observation, **settings):
        oracle.reset(told, observation)
        agent_reset(told, observation, **settings)

    agent.reset = reset
    return run_episode(instruction, world or SymbolicWorld(scene), agent, check, track=track)


def test_with_the_oracles_decisions_the_agent_answers_a_query_from_what_it_weighed(oracle_network):
    instruction, scene = _episode("measure_weight_multi")
    result = _play_with_oracle_decisions(oracle_network, instruction, scene)
    assert result.outcome is Outcome.SUCCESS
    assert isinstance(result.answer, Answer) and len(result.answer.value) >= 2


def test_after_failures_on_a_target_the_agent_passes_attempt(oracle_network):
    instruction, scene = _episode("stack_simple")

    class FailingFirstGrasps(SymbolicWorld):
        grasps = 0

        def apply(self, call):
            if call.name == "close_gripper" and self.grasps < 2:
                self.grasps += 1
                self.steps += 1
                return ActionResult(False, failure_reason="missed")
            return super().apply(call)

    result = _play_with_oracle_decisions(oracle_network, instruction, scene, FailingFirstGrasps(scene))
    assert result.outcome is Outcome.SUCCESS
    approaches = [a for a in result.actions if a.name == "approach"]
    assert [a.params.get("attempt") for a in approaches[:3]] == [None, 1, 2]


def test_the_language_track_needs_a_parser_and_uses_it(monkeypatch, oracle_network):
    instruction, scene = _episode("pick_up_lightest")
    agent = LearnedPlannerAgent(network=_Stub())
    observation = SymbolicWorld(scene).observe(None, 0)
    told = track_instruction(instruction, "language")
    assert told.program == []
    agent.reset(told, observation, track=Track.language)
    with pytest.raises(ConfigError, match=r"agent\.parser=PATH"):
        agent.act(told, observation)

    parsed = []

    class Parser:
        @classmethod
        def load(cls, path):
            assert path == "parser.pt"
            return cls()

        def parse(self, text):
            parsed.append(text)
            return track_instruction(instruction, "program").program

    monkeypatch.setitem(sys.modules, "muble_plugins.learned.parser", types.SimpleNamespace(InstructionParser=Parser))
    agent = LearnedPlannerAgent(network=_Stub(), parser="parser.pt")
    agent.reset(told, observation, track=Track.language)
    oracle_network["next"] = (CLASSES.index("move"), 1)
    assert isinstance(agent.act(told, observation), ActionCall)
    assert parsed == [instruction.instruction]


def test_masks_mode_needs_a_recogniser_and_image_mode_is_refused(monkeypatch, oracle_network):
    instruction, scene = _episode("move_single")
    observation = SymbolicWorld(scene).observe(None, 0)
    blank = dataclasses.replace(observation.scene, objects=[
        dataclasses.replace(o, name=None, colour=None, material=None, shape=None, size=None)
        for o in observation.scene.objects])
    masks = Observation(scene=blank, step=0)
    told = track_instruction(instruction, "program")
    unaided = LearnedPlannerAgent(network=_Stub())
    unaided.reset(told, masks, mode=ObservationMode.masks)
    with pytest.raises(ConfigError, match=r"agent\.recogniser=PATH"):
        unaided.act(told, masks)

    class Recogniser:
        @classmethod
        def load(cls, path):
            return cls()

        def recognise(self, obs):
            return {o.id: {k: getattr(o, k) for k in ("name", "colour", "material", "shape", "size", "stackable",
                                                     "stack_base", "pickupable")} for o in scene.objects}

    monkeypatch.setitem(sys.modules, "muble_plugins.learned.recogniser",
                        types.SimpleNamespace(AttributeRecogniser=Recogniser))
    oracle_network["next"] = (CLASSES.index(OracleAgent().act(told, observation).name), 1)
    agent = LearnedPlannerAgent(network=_Stub(), recogniser="recogniser.pt")
    agent.reset(told, masks, mode=ObservationMode.masks)
    assert isinstance(agent.act(told, masks), ActionCall)  # the program ran on the recognised words

    image = Observation(scene=dataclasses.replace(blank, objects=[]), step=0)
    with pytest.raises(ConfigError, match="image mode"):
        LearnedPlannerAgent(network=_Stub()).reset(told, image, mode=ObservationMode.image)


def test_stop_on_a_query_answers_once_then_stops(oracle_network):
    instruction, scene = _episode("measure_weight_single")
    agent = LearnedPlannerAgent(network=_Stub())
    observation = SymbolicWorld(scene).observe(None, 0)
    told = track_instruction(instruction, "program")
    agent.reset(told, observation)
    oracle_network["next"] = (CLASSES.index("stop"), IGNORE)
    # Nothing weighed yet: no answer can be given, so stopping is just stopping.
    assert agent.act(told, observation) is None

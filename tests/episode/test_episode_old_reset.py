"""An agent written for the earlier ``Agent.reset(instruction, observation)``, before ``track`` and ``mode`` were
passed, still plays its episodes: every runner calls ``reset`` without the keyword arguments it does not take, with
one ``DeprecationWarning`` per agent class (``muble.core.interfaces.reset_agent``)."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from muble import Agent, ObservationMode, Outcome, Track, get_registry
from muble.core.errors import MubleDeprecationWarning
from muble.core.interfaces import reset_agent
from muble.io.instructions_io import instruction_to_dict
from muble.io.scene_io import scene_to_dict


class OldOracle(Agent):
    """The built-in oracle behind a ``reset`` of the earlier signature."""

    privileged = True

    def __init__(self):
        self.inner = get_registry().create("agent", "oracle")
        self.resets = 0

    def reset(self, instruction, observation):
        self.resets += 1
        self.inner.reset(instruction, observation)

    def act(self, instruction, observation):
        return self.inner.act(instruction, observation)


class TakesAll(Agent):
    def reset(self, instruction, observation, **options):
        self.options = options

    def act(self, instruction, observation):
        return None


class TakesTrack(Agent):
    def reset(self, instruction, observation, track=Track.program):
        self.track = track

    def act(self, instruction, observation):
        return None


@pytest.fixture(scope="module")
def episode():
    """A measure_weight_single instruction on a synthetic scene."""
    from muble_plugins.common.synthetic import sample_scenes

    scene = sample_scenes(5, 1)[0]
    (instruction,) = get_registry().create("task", "measure_weight_single").generate(scene, np.random.default_rng(5))
    return instruction, scene


def _deprecations(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, MubleDeprecationWarning)]


def test_an_old_agent_plays_real_episodes_with_one_warning(episode):
    from muble_plugins.common.episodes import run_symbolic_episode

    instruction, scene = episode
    agent = OldOracle()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = [run_symbolic_episode(instruction, scene, agent) for _ in range(2)]
    assert [r.outcome for r in results] == [Outcome.SUCCESS] * 2, [r.error for r in results]
    assert agent.resets == 2 and all(r.actions for r in results)
    (message,) = _deprecations(caught)  # one for the class, not one per episode
    assert "OldOracle.reset takes no keyword argument 'track' or 'mode'" in message
    assert "reset(self, instruction, observation, *, track=Track.program, mode=ObservationMode.graph)" in message
    assert "MuBlE 0.2" in message


def test_an_old_agent_under_gymnasium_s_policy(episode):
    from muble.gym.policy import AgentPolicy

    instruction, scene = episode
    obs = {"scene": json.dumps(scene_to_dict(scene)), "measurements": "{}", "last_result": "null", "step": 0}
    info = {"instruction": instruction_to_dict(instruction), "track": "program", "mode": "graph"}
    policy = AgentPolicy(OldOracle())
    policy.reset(obs, info)
    assert policy.agent.resets == 1 and json.loads(policy(obs))["name"] == "move"


def test_reset_is_given_what_it_takes():
    told = (None, None)  # what it is told does not matter here
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        everything, one = TakesAll(), TakesTrack()
        reset_agent(everything, *told, track=Track.language, mode=ObservationMode.masks)
        reset_agent(one, *told, track=Track.language, mode=ObservationMode.masks)
    assert everything.options == {"track": Track.language, "mode": ObservationMode.masks}
    assert one.track is Track.language
    (message,) = _deprecations(caught)
    assert "TakesTrack.reset takes no keyword argument 'mode'" in message

"""An in-process ``Agent`` (the oracle, a baseline) as a policy for ``MuBlE/ShopVRB2-v0``.

The agent acts on what the environment's observation holds, rebuilt as an ``Observation`` (the agent-side scene
graph, the measurements, the last result, the images), so it sees nothing an external agent would not.
"""
from __future__ import annotations

import json
from typing import Any

from muble.core.interfaces import Agent, Instruction, reset_agent
from muble.core.types import Frame, Observation, ObservationMode, Track
from muble.episode.plain import decision_to_plain, observation_from_plain
from muble.io.instructions_io import instruction_from_dict


def observation_from_gym(obs: dict[str, Any]) -> Observation:
    """The ``Observation`` an in-process agent would get, from a ShopVRB2 observation."""
    data = {"scene": json.loads(obs["scene"]), "measurements": json.loads(obs["measurements"]),
            "last_result": json.loads(obs["last_result"]), "step": int(obs["step"])}
    images = {camera: Frame(camera=camera, rgb=rgb) for camera, rgb in (obs.get("images") or {}).items()}
    return observation_from_plain(data, images)


class AgentPolicy:
    """``policy.reset(obs, info)`` at each reset, then ``action = policy(obs)`` for every step."""

    def __init__(self, agent: Agent):
        self.agent = agent
        self.instruction: Instruction | None = None

    def reset(self, obs: dict[str, Any], info: dict[str, Any]) -> None:
        self.instruction = instruction_from_dict(info["instruction"])
        reset_agent(self.agent, self.instruction, observation_from_gym(obs), track=Track(info["track"]),
                    mode=ObservationMode(info["mode"]))

    def __call__(self, obs: dict[str, Any]) -> str:
        if self.instruction is None:
            raise RuntimeError("call reset(obs, info) with the environment's reset output first")
        decision = self.agent.act(self.instruction, observation_from_gym(obs))
        return json.dumps(decision_to_plain(decision))

"""The random agent: a baseline of uniformly random primitives."""
from __future__ import annotations

import zlib
from dataclasses import dataclass

from muble import ActionCall, Agent, Answer, Instruction, Observation, ObservationMode, Track
from muble.core import streams
from muble.core.ranges import configured

from muble_plugins.common.symbolic import APPROACH, GRASP, LIFT, LOWER, MOVE, RELEASE, WEIGH

# Seeded as before named streams (legacy_stream): docs/results.md's random row was measured with these draws.
EPISODE_STREAM = streams.declare_legacy(
    "agent.random", "the random agent's stops, primitives and targets in an episode (agent.seed and the crc32 of "
    "split/scene index/template)")


@dataclass
class RandomConfig:
    seed: int = 0
    stop_probability: float = 0.05  # chance per step of declaring the task done


class RandomAgent(Agent):
    """Uniformly random primitives on random objects: the floor every reasoner should beat.

    Built from a ``RandomConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``RandomAgent(seed=3)``).
    """

    def __init__(self, config: RandomConfig | None = None, **options) -> None:
        self.config = configured(RandomConfig, config, options, owner="agent 'random'")
        self.rng = streams.legacy_stream(EPISODE_STREAM, self.config.seed)

    def reset(self, instruction: Instruction, observation: Observation, *, track: Track = Track.program,
              mode: ObservationMode = ObservationMode.graph) -> None:
        # Each episode its own stream, reproducible from (seed, split, scene index, template).
        episode = zlib.crc32(f"{instruction.split}/{instruction.image_index}/{instruction.template_id}".encode())
        self.rng = streams.legacy_stream(EPISODE_STREAM, self.config.seed, episode)

    def act(self, instruction: Instruction, observation: Observation) -> ActionCall | Answer | None:
        if self.rng.random() < self.config.stop_probability:
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

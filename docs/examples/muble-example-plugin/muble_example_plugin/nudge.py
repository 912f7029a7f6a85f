"""A third-party disturbance: ``nudge``, a short push on a resting object, as a bumped table would give.

Written against MuBlE's public API only (``muble.Disturbance``, ``muble.DisturbanceEvent`` and the environment's
``apply_force``/``advance``): its trigger is drawn in ``reset`` from the stream MuBlE hands it, it acts through a
force that MuJoCo integrates, and it returns the event it applied so that the episode record keeps it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import muble


@dataclass
class NudgeConfig:
    after: int = muble.bounded(3, ge=1)  # it acts after one of the first `after` primitives (drawn)
    strength: float = muble.bounded(0.8, gt=0.0, le=3.0)  # the push, in the object's weights
    duration: float = muble.bounded(0.1, gt=0.0, le=1.0)  # s the push lasts


class Nudge(muble.Disturbance):
    """After the drawn primitive, the object standing nearest the robot's hand (not held) is pushed sideways low
    on its side, in a drawn direction, for a moment; then it comes to rest wherever the physics leaves it."""

    def __init__(self, config: NudgeConfig):
        self.config = config
        self.step, self.angle, self.fired = 1, 0.0, False

    def reset(self, rng: np.random.Generator, scene) -> None:
        self.step = int(rng.integers(1, self.config.after + 1))
        self.angle = float(rng.uniform(0.0, 2 * np.pi))
        self.fired = False

    def after(self, env, action, result, step: int):
        if self.fired or step < self.step:
            return result, None
        hand = env.ee_pose().pos[:2]
        resting = [i for i in env.object_ids if i != env.held_object and env.touches_support(i)]
        if not resting:
            return result, None
        target = min(resting, key=lambda i: float(np.linalg.norm(env.object_pose(i).pos[:2] - hand)))
        mass = float(env.model.body_subtreemass[env.model.body(env.names.objects[target]).id])
        force = self.config.strength * mass * 9.81 * np.array([np.cos(self.angle), np.sin(self.angle), 0.0])
        low = env.object_top(target) - env.world_bbox(target)["z"] + 0.003
        position = env.object_pose(target).pos
        env.apply_force(target, force, np.array([position[0], position[1], low]))
        env.advance(self.config.duration)
        env.apply_force(target, np.zeros(3))
        env.advance(1.0)
        self.fired = True
        return result, muble.DisturbanceEvent("nudge", step, f"after primitive {self.step}", target,
                                              force=force.tolist(),
                                              impulse=(force * self.config.duration).tolist(),
                                              duration=self.config.duration)

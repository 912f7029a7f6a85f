"""A policy loop on the MuBlE Gymnasium environments.

    MUJOCO_GL=egl python docs/examples/gym_policy_loop.py            # the oracle on ShopVRB2-v0, three episodes
    MUJOCO_GL=egl python docs/examples/gym_policy_loop.py tabletop   # a scripted reach-down-and-close on Tabletop-v0

The ShopVRB2 loop is what a learned reasoner replaces: read ``obs["instruction"]``, ``obs["images"]`` and the
JSON scene graph in ``obs["scene"]``, return a primitive call as JSON text. Here the built-in oracle decides,
wrapped by ``AgentPolicy`` so it sees only what the observation holds.
"""
from __future__ import annotations

import json
import sys

import gymnasium
import numpy as np

import muble.gym  # noqa: F401 - registers MuBlE/ShopVRB2-v0 and MuBlE/Tabletop-v0
from muble import get_registry
from muble.gym.policy import AgentPolicy


def shopvrb2(episodes: int = 3) -> None:
    env = gymnasium.make("MuBlE/ShopVRB2-v0", templates=["measure_weight_single", "move_single", "stack_simple"],
                         overrides=["renderer.width=320", "renderer.height=240"])
    policy = AgentPolicy(get_registry().create("agent", "oracle", {}))
    returns = []
    for episode in range(episodes):
        obs, info = env.reset(seed=episode)
        policy.reset(obs, info)
        print(f"episode {episode}: {obs['instruction']}")
        done, reward = False, 0.0
        while not done:
            action = policy(obs)
            obs, reward, terminated, truncated, info = env.step(action)
            result = json.loads(obs["last_result"])
            print(f"  {action} -> {'ok' if result and result['success'] else result}")
            done = terminated or truncated
        print(f"  outcome {info['outcome']}, reward {reward}")
        returns.append(reward)
    env.close()
    print(f"success rate {np.mean(returns):.2f} over {episodes} episodes")


def tabletop(steps: int = 60) -> None:
    env = gymnasium.make("MuBlE/Tabletop-v0")
    obs, info = env.reset(seed=0)
    for t in range(steps):
        # Down for 2 s, then close the gripper: a stand-in for a learned visuomotor policy reading obs["image"].
        action = np.array([0, 0, -0.2, 0, 0, 0, -1 if t < 40 else 1], dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    print(f"end-effector at {np.round(obs['ee_pos'], 3)}, gripper opening {obs['gripper_opening'][0]:.3f} m, "
          f"image {obs['image'].shape}")
    env.close()


if __name__ == "__main__":
    tabletop() if sys.argv[1:] == ["tabletop"] else shopvrb2()

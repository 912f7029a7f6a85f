"""Gymnasium environments of MuBlE, registered on import:

- ``MuBlE/ShopVRB2-v0``: one SHOP-VRB2 episode; actions are primitive calls as JSON text (``muble.gym.shopvrb2``);
- ``MuBlE/Tabletop-v0``: continuous end-effector control with gripper; image and proprioception
  (``muble.gym.tabletop``).

    import gymnasium, muble.gym
    env = gymnasium.make("MuBlE/ShopVRB2-v0", overrides=["renderer.width=640"])

``gymnasium.make("muble.gym:MuBlE/ShopVRB2-v0")`` imports this module itself.
"""
from __future__ import annotations

import gymnasium

SHOPVRB2_ID = "MuBlE/ShopVRB2-v0"
TABLETOP_ID = "MuBlE/Tabletop-v0"


def register_environments() -> None:
    """Register both environments with Gymnasium (again is harmless)."""
    registered = gymnasium.envs.registry
    if SHOPVRB2_ID not in registered:
        # No max_episode_steps: the action loop ends the episode itself (episode.max_steps, as a truncation).
        gymnasium.register(SHOPVRB2_ID, entry_point="muble.gym.shopvrb2:ShopVRB2Env")
    if TABLETOP_ID not in registered:
        gymnasium.register(TABLETOP_ID, entry_point="muble.gym.tabletop:TabletopGymEnv", max_episode_steps=400)


register_environments()

__all__ = ["SHOPVRB2_ID", "TABLETOP_ID", "register_environments"]

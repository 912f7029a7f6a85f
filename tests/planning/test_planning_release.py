"""Letting go is checked in physics: an object the fingers still hold up after the release is a failed put-down,
whatever the weld says. The scene is one generated on the original stage, where the Robotiq 85's fingertips,
inside a glass it picked by the rim, keep it wedged after they open."""
from __future__ import annotations

from pathlib import Path

from muble import get_registry
from muble.core.scene_io import load_scene
from muble.sim.build import env_from_object_set
from muble.sim.initial_state import settle_and_check

SCENE = Path(__file__).parent / "data" / "robotiq_glass_left_hanging.json"


def test_an_object_left_hanging_in_the_fingers_is_not_put_down():
    scene = load_scene(SCENE)
    env = env_from_object_set(scene, "shopvrb2")
    try:
        env.reset()
        settle_and_check(env)
        registry = get_registry()
        env.planner = registry.create("planner", "ompl", {})
        for name, params in [("move", {"target": 1}), ("approach", {"target": 1}), ("close_gripper", {"target": 1}),
                             ("lift", {})]:
            result = registry.create("primitive", name, params).execute(env)
            assert result.success, (name, result.failure_reason)
        result = registry.create("primitive", "lower", {}).execute(env)
        assert env.held_object is None  # the weld is off ...
        assert env.object_pose(1).pos[2] > 0.03  # ... yet the glass is up in the hand, on nothing
        assert not result.success
        assert result.failure_reason == "object 1 hangs in the open fingers after it was let go, resting on nothing"
    finally:
        env.close()

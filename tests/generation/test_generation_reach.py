"""The generator's reach check: every pickupable object can be grasped by the robot and put down again."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from muble import get_registry
from muble.generation.reachability import ReachCheck
from muble.io.scene_io import load_scene
from muble.sim.build import env_from_object_set, object_models

pytestmark = pytest.mark.slow

SCENE = Path(__file__).parents[1] / "planning" / "data" / "glass_beside_a_tall_thermos.json"



def test_a_scene_whose_objects_are_all_within_reach_passes(object_set):
    scene = load_scene(SCENE)
    assert ReachCheck(None, "approach")(scene, object_models(scene, object_set)) is None


def test_an_object_beyond_the_arms_reach_is_named(object_set):
    scene = copy.deepcopy(load_scene(SCENE))
    far = next(o for o in scene.objects if o.pickupable)
    far.position = np.array([0.86, -0.56, 0.0])
    reason = ReachCheck(None, "approach")(scene, object_models(scene, object_set))
    assert reason is not None and reason.startswith(f"object {far.id} ({far.name}) at (0.86, -0.56)")


def test_feasible_moves_nothing():
    scene = load_scene(SCENE)
    env = env_from_object_set(scene, "shopvrb2")
    try:
        before = env.data.qpos.copy(), env.data.time, env.gripper_command
        target = next(o.id for o in scene.objects if o.pickupable)
        get_registry().create("primitive", "approach", {"target": target}).feasible(env)
        assert np.array_equal(env.data.qpos, before[0]) and env.data.time == before[1]
        assert env.gripper_command == before[2] and env.held_object is None
    finally:
        env.close()


def test_an_object_under_the_hand_at_rest_is_refused_on_the_original_stage(object_set):
    """The original stage's arm rests with its fingers 0.15 m over the table's middle: a tall object there would
    be in the first move's way, so the layout is refused; the same place is fine on robosuite's stage."""
    scene = copy.deepcopy(load_scene(SCENE))
    tall = max(scene.objects, key=lambda o: o.bbox["z"])
    tall.position = np.array([0.5, 0.0, tall.position[2]])
    others = [o for o in scene.objects if o is not tall]
    for k, o in enumerate(others):  # out of the way
        o.position = np.array([0.35 + 0.15 * k, -0.3, o.position[2]])
    scene.objects = [tall, *others]
    check = ReachCheck(None, "approach")
    assert tall.bbox["z"] > 0.2
    assert check(scene, object_models(scene, object_set)) is None
    scene.extra["stage"] = "original"
    reason = check(scene, object_models(scene, object_set))
    assert reason is not None and reason.startswith(f"object {tall.id} ({tall.name}) at (0.5, 0.0)")
    assert "from the robot at rest, as built" in reason

import numpy as np
import pytest

import muble
from muble.sim.env import TabletopEnv
from muble_plugins.primitives.measure import weigh
from tests.sim.conftest import pick

SENSORS = ["wrist_ft", "gripper", "ee_pose", "joints", "objects", "weight", "stiffness"]


@pytest.fixture(scope="module")
def sensed_env(scene_models):
    scene, models = scene_models
    registry = muble.get_registry()
    return TabletopEnv(scene, models, sensors={n: registry.create("sensor", n) for n in SENSORS})


def test_sim_builtin_sensors_are_registered():
    assert set(SENSORS) <= set(muble.get_registry().names("sensor"))


def test_sim_sensors_report_a_grasp_and_a_weighing(sensed_env, scene_models):
    env = sensed_env
    env.reset()
    obs = env.observation()
    assert obs["gripper"]["held_object"] is None
    assert np.allclose(obs["ee_pose"]["position"], env.ee_pose().pos)
    assert obs["joints"]["position"].shape == (7,)
    assert obs["objects"][2]["bbox"]["z"] == pytest.approx(0.05, abs=1e-6)
    _, models = scene_models
    pick(env, 2, models[2].extents[2])
    grams = weigh(env)
    obs = env.observation()
    assert obs["gripper"]["held_object"] == 2
    assert obs["objects"][2]["in_hand"] and obs["objects"][2]["raised"]
    assert not obs["objects"][0]["in_hand"]
    assert obs["weight"] == {2: pytest.approx(grams)}
    # the tared force is the held weight, pulling down
    assert obs["wrist_ft"]["force_tared"][2] / 9.81 * 1000 == pytest.approx(grams, abs=2.0)

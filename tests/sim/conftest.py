import numpy as np
import pytest

from muble.sim.env import TabletopEnv
from tests.support.scenes import five_object_scene


@pytest.fixture(scope="module")
def scene_models():
    return five_object_scene()


@pytest.fixture(scope="module")
def panda_env(scene_models):
    scene, models = scene_models
    return TabletopEnv(scene, models)


def drive_to(env, goal, gripper, steps):
    """Scripted proportional control through the Gymnasium API; returns the final position error (m)."""
    for _ in range(steps):
        action = np.zeros(7)
        action[:3] = np.clip((goal - env.ee_pose().pos) / 0.05, -1, 1)
        action[6] = gripper
        _, _, terminated, _, info = env.step(action)
        assert not terminated, info
    return float(np.linalg.norm(goal - env.ee_pose().pos))


def pick(env, obj_id, height, lift=0.12):
    """Approach from above, tare, descend, close, lift: leaves ``obj_id`` in the hand."""
    p = env.object_pose(obj_id).pos
    drive_to(env, p + [0, 0, height + 0.08], -1, 60)
    env.hold(0.3)
    env.tare()
    drive_to(env, p + [0, 0, height * 0.6], -1, 40)
    drive_to(env, p + [0, 0, height * 0.6], 1, 20)
    drive_to(env, p + [0, 0, height + lift], 1, 40)

"""The wrist force/torque sensor's noise (``muble.sim.sensor_noise``): off, it reads what MuJoCo computes, bit for
bit, and draws nothing; on, weighings spread as its model says, and an episode's readings are a function of its
seed and key.

The spread is measured in physics: one object of the five-object scene weighed 20 times, each time from the same
state with the empty hand over it (restored), tared, grasped, lifted and weighed, so the physics of every weighing
is the same and only the sensor errs."""
from __future__ import annotations

import math

import numpy as np
import pytest

from muble.core import streams
from muble.core.environment import GRAVITY
from muble.sim.env import TabletopEnv
from muble.sim.sensor_noise import TARE_WINDOW, WristNoise, WristSensorNoise
from muble_plugins.primitives.measure import WEIGH_SETTLE, WEIGH_WINDOW, weigh

from tests.sim.conftest import drive_to

NOISY = {"force_white_n": 0.1, "force_drift_n_per_sqrt_s": 0.04, "torque_white_nm": 0.005,
         "torque_drift_nm_per_sqrt_s": 0.002}
OBJ = 0  # the 180 g box


def _over(env, obj_id: int = OBJ) -> float:
    """Drive the empty hand over the object and hold it still there (where a tare is taken); its height."""
    height = env.scene.object(obj_id).bbox["z"]
    drive_to(env, env.object_pose(obj_id).pos + [0, 0, height + 0.08], -1, 60)
    env.hold(0.3)
    return height


def _grasp_and_lift(env, height: float, obj_id: int = OBJ) -> None:
    """From over the object, tared: descend, close, lift (``tests.sim.conftest.pick`` after its tare)."""
    p = env.object_pose(obj_id).pos
    drive_to(env, p + [0, 0, height * 0.6], -1, 40)
    drive_to(env, p + [0, 0, height * 0.6], 1, 20)
    drive_to(env, p + [0, 0, height + 0.12], 1, 40)
    assert env.held_object == obj_id


def test_sim_a_perfect_sensor_reads_what_mujoco_computes_and_draws_nothing(scene_models, monkeypatch):
    scene, models = scene_models
    plain = TabletopEnv(scene, models)
    monkeypatch.setattr(streams, "stream", lambda *a, **k: pytest.fail("a perfect sensor drew from a stream"))
    zeros = TabletopEnv(scene, models, noise={name: 0.0 for name in NOISY}, noise_stream=(3, 7))
    assert zeros.sensor_noise.perfect and zeros._wrist_noise is None
    readings = []
    for env in (plain, zeros):
        height = _over(env)
        env.tare()
        _grasp_and_lift(env, height)
        raw = env.data.site_xmat[env.ft_site_id].reshape(3, 3) @ env.data.sensordata[env.force_adr:env.force_adr + 3]
        assert np.array_equal(env.wrist_wrench()[0], raw)
        readings.append((weigh(env), env.tare_force.copy(), env.snapshot().state))
    assert readings[0][0] == readings[1][0]
    assert np.array_equal(readings[0][1], readings[1][1]) and np.array_equal(readings[0][2], readings[1][2])


def test_sim_the_noise_model_draws_white_noise_per_sample_and_a_drifting_bias():
    """The model alone, read at the physics rate: the white noise holds for an output sample (10 ms) and has its
    stated spread; the bias walks by drift·√(elapsed); a zeroing averages the white noise of its window."""
    spec = WristNoise(force_white_n=0.1, force_drift_n_per_sqrt_s=0.04, torque_white_nm=0.005,
                      torque_drift_nm_per_sqrt_s=0.002)
    white_only = WristSensorNoise(WristNoise(force_white_n=0.1, torque_white_nm=0.005), 0, 1)
    samples = np.array([white_only.error(k * 0.002) for k in range(20000)])
    assert np.array_equal(samples[0], samples[4]) and not np.array_equal(samples[4], samples[5])
    per_sample = samples[::5]  # one per output sample
    assert per_sample[:, :3].std() == pytest.approx(0.1, rel=0.05)
    assert per_sample[:, 3:].std() == pytest.approx(0.005, rel=0.05)
    drift_only = WristNoise(force_drift_n_per_sqrt_s=0.04, torque_drift_nm_per_sqrt_s=0.002)

    def walk(key: int) -> np.ndarray:
        model = WristSensorNoise(drift_only, 0, key)
        before = model.error(10.0)
        return model.error(14.0) - before

    steps = np.array([walk(k) for k in range(600)])
    assert steps[:, :3].std() == pytest.approx(0.04 * 2.0, rel=0.08)  # 4 s: drift·√4
    assert steps[:, 3:].std() == pytest.approx(0.002 * 2.0, rel=0.08)
    zeros = np.array([WristSensorNoise(WristNoise(force_white_n=0.1), 0, k).zero_error(1.0) for k in range(600)])
    assert zeros[:, :3].std() == pytest.approx(0.1 / math.sqrt(TARE_WINDOW * 100), rel=0.08)
    assert not WristNoise.of(spec).perfect and WristNoise.of(None).perfect


def test_sim_same_seed_and_key_read_the_same_and_another_key_otherwise(scene_models):
    scene, models = scene_models

    def readings(env):
        env.reset()
        out = [env.tare().copy()]
        for _ in range(5):
            env.advance(0.1)
            out.append(np.concatenate(env.wrist_wrench()))
        return np.concatenate(out)

    first = TabletopEnv(scene, models, noise=NOISY, noise_stream=(0, 4))
    again = readings(first)
    assert np.array_equal(readings(first), again)  # reset: the episode's stream from its start
    assert np.array_equal(readings(TabletopEnv(scene, models, noise=NOISY, noise_stream=(0, 4))), again)
    for other in ((0, 5), (1, 4)):
        assert not np.allclose(readings(TabletopEnv(scene, models, noise=NOISY, noise_stream=other)), again)
    perfect = readings(TabletopEnv(scene, models))
    assert np.abs(again - perfect).max() < 1.0 and not np.allclose(again, perfect)


def test_sim_noisy_weighings_spread_as_the_model_says(scene_models):
    """20 weighings of one object from the same state: each error against the perfect sensor's reading of the same
    physics has the spread the model gives (the bias's walk from the tare to the reading window and over it, the
    white noise of the tare and of the reading, each averaged over 0.2 s of 100 Hz samples)."""
    scene, models = scene_models
    perfect = TabletopEnv(scene, models)
    height = _over(perfect)
    start = perfect.snapshot()
    perfect.tare()
    tared_at = perfect.data.time
    _grasp_and_lift(perfect, height)
    truth = weigh(perfect)
    delay = perfect.data.time - WEIGH_WINDOW - tared_at  # tare to the reading window's start
    assert abs(truth - scene.object(OBJ).weight_gt) < 1.0

    env = TabletopEnv(scene, models, noise=NOISY, noise_stream=(0, 11))
    _over(env)
    assert np.array_equal(env.snapshot().state, start.state)
    errors = []
    for _ in range(20):
        env.restore(start)
        env.tare()
        _grasp_and_lift(env, height)
        errors.append(weigh(env) - truth)
    errors = np.array(errors)
    drift, white = NOISY["force_drift_n_per_sqrt_s"], NOISY["force_white_n"]
    variance = drift ** 2 * (delay + WEIGH_WINDOW / 3) + white ** 2 / (WEIGH_WINDOW * 100) \
        + white ** 2 / (TARE_WINDOW * 100)
    expected = math.sqrt(variance) / GRAVITY * 1000.0
    assert delay == pytest.approx(5.0 + WEIGH_SETTLE, abs=0.06)
    assert 0.65 * expected < errors.std(ddof=1) < 1.4 * expected, (errors.round(2), expected)
    assert abs(errors.mean()) < 3 * expected / math.sqrt(len(errors)), (errors.round(2), expected)

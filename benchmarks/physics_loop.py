"""Physics-loop throughput against raw ``mj_step`` on the same model, measured in the same run.

Figures: physics steps per second of (a) raw ``mj_step`` on the environment's model replaying the identical
motion (the recorded controls; also at rest, where the solver has less to do), (b) ``TabletopEnv.follow``
tracking a joint trajectory (primitive execution), (c) ``TabletopEnv.step`` with OSC_POSE actions (scripted
control), and, as the reference, (d) robosuite's stock Lift + Panda OSC loop against raw ``mj_step`` on its model.
The value is (b)/(a); the goal is 0.60.
"""
from __future__ import annotations

import json
import logging
import time

import mujoco
import numpy as np

from muble.core.types import Trajectory
from muble.sim.env import TabletopEnv
from muble.sim.fixtures import five_object_scene

SIM_SECONDS = 10.0


def raw_rate(model, data, seconds: float = SIM_SECONDS) -> float:
    n = int(seconds / model.opt.timestep)
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=n)
    return n / (time.perf_counter() - start)


def follow_rate(env: TabletopEnv, record: list | None = None) -> float:
    """Steps/s of ``follow``; ``record`` receives (state before, ctrl per control step) for the replay."""
    q0 = env.arm_q()
    t = np.linspace(0.0, SIM_SECONDS, 21)
    q = q0 + 0.3 * np.sin(2 * np.pi * t / SIM_SECONDS)[:, None] * np.array([1, 0.5, 1, 0.5, 1, 1, 1])[: len(q0)]
    steps0 = env.data.time
    if record is not None:
        record.append(env.snapshot())
    start = time.perf_counter()
    env.follow(Trajectory(q, t))
    elapsed = time.perf_counter() - start
    return (env.data.time - steps0) / env.model.opt.timestep / elapsed


def replay_rate(env: TabletopEnv, snap, trajectory_ctrl: np.ndarray) -> float:
    """Raw ``mj_step`` on the identical motion: the recorded controls, no Python besides setting them."""
    data = mujoco.MjData(env.model)
    mujoco.mj_setState(env.model, data, snap.state, mujoco.mjtState.mjSTATE_INTEGRATION)
    ids = env.servos.actuator_ids
    k = env.n_substeps
    start = time.perf_counter()
    for ctrl in trajectory_ctrl:
        data.ctrl[ids] = ctrl
        mujoco.mj_step(env.model, data, nstep=k)
    return len(trajectory_ctrl) * k / (time.perf_counter() - start)


def recorded_ctrl(env: TabletopEnv, snap) -> np.ndarray:
    """The arm controls ``follow`` applies for the benchmark trajectory, captured by re-running it."""
    env.restore(snap)
    ctrls = []
    original = env.servos.command

    def capture(data, q_target, qd_target=None):
        original(data, q_target, qd_target)
        ctrls.append(data.ctrl[env.servos.actuator_ids].copy())

    env.servos.command = capture
    follow_rate(env)
    env.servos.command = original
    return np.array(ctrls)


def step_rate(env: TabletopEnv) -> float:
    count = int(SIM_SECONDS / env.control_dt)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.2, 0.2, size=(count, 7))
    actions[:, 6] = -1
    start = time.perf_counter()
    for a in actions:
        env.step(a)
    elapsed = time.perf_counter() - start
    return count * env.n_substeps / elapsed


def robosuite_rates() -> tuple[float, float]:
    import robosuite

    env = robosuite.make("Lift", robots="Panda", has_renderer=False, has_offscreen_renderer=False,
                         use_camera_obs=False, control_freq=20)
    env.reset()
    substeps = int(env.control_timestep / env.model_timestep)
    count = 100
    start = time.perf_counter()
    for _ in range(count):
        env.step(np.zeros(env.action_dim))
    stock = count * substeps / (time.perf_counter() - start)
    model, data = env.sim.model._model, env.sim.data._data
    raw = raw_rate(model, data, 5.0)
    env.close()
    return stock, raw


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    scene, models = five_object_scene()
    env = TabletopEnv(scene, models)
    scratch = mujoco.MjData(env.model)
    mujoco.mj_copyData(scratch, env.model, env.data)
    raw_rate(env.model, scratch, 1.0)  # warm-up
    raw_rest = np.median([raw_rate(env.model, scratch) for _ in range(3)])
    snaps: list = []
    follow = np.median([follow_rate(env, snaps) for _ in range(3)])
    ctrl = recorded_ctrl(env, snaps[0])
    raw = np.median([replay_rate(env, snaps[0], ctrl) for _ in range(3)])
    env.reset()
    step = step_rate(env)
    try:
        stock, stock_raw = robosuite_rates()
        reference = {"robosuite_lift_osc_steps_per_s": round(stock), "robosuite_raw_steps_per_s": round(stock_raw),
                     "robosuite_ratio": round(stock / stock_raw, 3)}
    except AssertionError as e:  # robosuite 1.5.2's own envs fail at reset with some MuJoCo releases
        reference = {"robosuite_ratio": None, "robosuite_error": f"robosuite Lift failed at reset with mujoco "
                     f"{mujoco.__version__}: AssertionError {e}".strip()}
    result = {
        "benchmark": "physics_loop", "metric": "follow_steps_per_s / raw_mj_step_steps_per_s (same motion)",
        "value": round(float(follow / raw), 3), "unit": "ratio", "goal": 0.60,
        "raw_steps_per_s": round(float(raw)), "raw_at_rest_steps_per_s": round(float(raw_rest)),
        "follow_ratio_vs_raw_at_rest": round(float(follow / raw_rest), 3), "follow_steps_per_s": round(float(follow)),
        "osc_step_steps_per_s": round(float(step)), "osc_step_ratio": round(float(step / raw), 3),
        **reference,
        "settings": {"robot": "Panda", "control_freq": 20, "timestep": 0.002, "objects": 5},
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()

"""Physical measurements through the robot: weight from the wrist force sensor, stiffness from squeezing.

Both read what the simulated hardware reports (sensor forces, finger pad positions); neither looks at the ground
truth stored in the model.
"""
from __future__ import annotations

import logging

import numpy as np

from muble.core.errors import PhysicsError

logger = logging.getLogger(__name__)

GRAVITY = 9.81
WEIGH_SETTLE = 0.6  # s of holding still before reading; see docs/environment.md for how it was chosen
WEIGH_WINDOW = 0.2  # s over which the force is averaged


def mean_wrist_force(env, window: float = WEIGH_WINDOW) -> np.ndarray:
    """Wrist force (world frame) averaged over ``window`` seconds, sampled every control step while holding."""
    samples = []
    env.advance(window, on_control=lambda k: samples.append(env.wrist_wrench()[0].copy()))
    samples.append(env.wrist_wrench()[0].copy())
    return np.mean(samples, axis=0)


def weigh(env, settle: float = WEIGH_SETTLE, window: float = WEIGH_WINDOW) -> float:
    """Weight in grams of what the hand holds: hold still, read the wrist force, subtract the tare, divide by g.

    Needs a tare taken with the empty hand (``env.tare()``, before grasping).
    """
    if env.tare_force is None:
        raise PhysicsError("no tare: call env.tare() with the empty hand, before grasping, then weigh")
    env.hold(settle)
    force = mean_wrist_force(env, window)
    # Sign measured: a held load adds +z to the world-frame reading of this sensor.
    extra = force - env.tare_force
    grams = float(extra[2] / GRAVITY * 1000.0)
    if env.held_object is not None:
        env.measurements.setdefault(env.held_object, {})["weight"] = grams
    return grams


SQUEEZE_FORCES = (5.0, 10.0, 15.0)  # N per finger
SQUEEZE_SETTLE = 0.5  # s at each force level


def pad_contact_force(env, obj_id: int) -> float:
    """Mean normal force (N) of the finger pads on ``obj_id``, summed per finger side."""
    import mujoco

    data, grasp = env.data, env.grasp
    per_side = np.zeros(3)
    wrench = np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        for pad, other in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
            side = grasp.pad_side[pad]
            if side and grasp.geom_object[other] == obj_id:
                mujoco.mj_contactForce(env.model, data, i, wrench)
                per_side[side] += wrench[0]
    return float(per_side[1:].mean())


def squeeze(env, obj_id: int, forces=SQUEEZE_FORCES, settle: float = SQUEEZE_SETTLE) -> float:
    """Stiffness (N/m) of the object between the fingers: close at each force level, record the pad force and
    the pad separation, fit force against the closure of one side (half the separation change)."""
    ids = env.gripper_actuator_ids
    saved = env.model.actuator_forcerange[ids].copy()
    samples = []
    try:
        for level in forces:
            env.model.actuator_forcerange[ids] = (-level, level)
            env.close_gripper()
            env.hold(settle)
            samples.append((pad_contact_force(env, obj_id), env.gripper_opening()))
    finally:
        env.model.actuator_forcerange[ids] = saved
    force, opening = np.array(samples).T
    if np.any(force <= 0):
        raise PhysicsError(f"the pads do not both touch object {obj_id} while squeezing; grasp it first")
    slope = np.polyfit(-opening / 2.0, force, 1)[0]
    env.measurements.setdefault(obj_id, {})["stiffness"] = float(slope)
    return float(slope)

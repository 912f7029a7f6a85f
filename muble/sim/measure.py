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


SQUEEZE_FORCES = (5.0, 10.0, 15.0)  # N per finger: the actuators' force limit at each level
SQUEEZE_SETTLE = 0.5  # s at each force level before reading
SQUEEZE_WINDOW = 0.1  # s over which jaw force and finger position are averaged


def jaw_forces(env, obj_id: int) -> np.ndarray:
    """Force (N) with which ``obj_id`` pushes back on each jaw (left, right), along each finger's closing axis:
    the contact forces between the object and every geom of that finger, as a force sensor in the finger reads."""
    import mujoco

    model, data = env.model, env.data
    sides = env.grasp.jaws.jaw_side
    geom_object = env.grasp.geom_object
    out = np.zeros(2)
    wrench = np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        for finger, other, sign in ((c.geom1, c.geom2, -1.0), (c.geom2, c.geom1, 1.0)):
            side = sides[finger]
            if side and geom_object[other] == obj_id:
                mujoco.mj_contactForce(model, data, i, wrench)
                # contact frame row 0 is the normal, pointing from geom1 to geom2; force on geom2 is +normal
                force = sign * wrench[0] * c.frame[:3]
                out[side - 1] += float(force @ _closing_axis(env, side - 1))
    return -out


def _closing_axis(env, k: int) -> np.ndarray:
    """World direction in which finger ``k`` moves when the gripper closes."""
    model, data = env.model, env.data
    jnt = model.joint(env.names.gripper_joints[k]).id
    axis = data.xaxis[jnt]
    sign = np.sign(env.gripper_closed_ctrl[k] - env.gripper_open_ctrl[k]) or 1.0
    return sign * axis


def finger_closure(env) -> np.ndarray:
    """Travel (m) of each finger joint in its closing direction, from the joints' encoders."""
    q = env.data.qpos[env.gripper_qpos_adr]
    sign = np.sign(env.gripper_closed_ctrl - env.gripper_open_ctrl)
    sign[sign == 0] = 1.0
    return q * sign


def squeeze(env, obj_id: int | None = None, forces=SQUEEZE_FORCES, settle: float = SQUEEZE_SETTLE,
            window: float = SQUEEZE_WINDOW) -> float:
    """Stiffness (N/m) of the object between the fingers (default: the one in the hand).

    At each force level the finger actuators are limited to that force and commanded closed; after ``settle`` s
    the jaw forces and the finger positions are averaged over ``window`` s. The stiffness is the least-squares
    slope of the mean jaw force against the mean finger travel: force per metre a jaw penetrates the object.
    The arm holds its pose throughout; the object stays welded to the hand if it was grasped (``grasp="weld"``),
    which keeps the two jaws' loads symmetric about it.
    """
    obj_id = env.held_object if obj_id is None else obj_id
    if obj_id is None:
        raise PhysicsError("nothing between the fingers to squeeze: grasp an object first (or pass obj_id)")
    forces = [float(f) for f in forces]
    if len(forces) < 2 or len(set(forces)) < 2:
        raise PhysicsError(f"squeeze needs at least two different force levels, got {forces}")
    ids = env.gripper_actuator_ids
    saved = env.model.actuator_forcerange[ids].copy()
    saved_limited = env.model.actuator_forcelimited[ids].copy()
    saved_ctrl_limited = env.model.actuator_ctrllimited[ids].copy()
    # The finger servos are commanded a full stroke beyond "closed", so that the force limit, not the servo's
    # position error, sets the squeezing force: on a narrow part (a thin glass, a handle, a stem) the fingers stop
    # a few millimetres short of closed, where the servo alone pushes with only a few newtons at every level.
    push = env.gripper_closed_ctrl + (env.gripper_closed_ctrl - env.gripper_open_ctrl)
    samples = []
    try:
        env.model.actuator_ctrllimited[ids] = 0
        for level in forces:
            env.model.actuator_forcerange[ids] = (-level, level)
            env.model.actuator_forcelimited[ids] = 1
            env.close_gripper()
            env.data.ctrl[ids] = push
            env.hold(settle)
            window_samples = []

            def read(_k):
                window_samples.append(np.concatenate([jaw_forces(env, obj_id), finger_closure(env)]))

            env.advance(window, on_control=read)
            force_l, force_r, travel_l, travel_r = np.mean(window_samples, axis=0)
            samples.append((0.5 * (force_l + force_r), 0.5 * (travel_l + travel_r), min(force_l, force_r)))
    finally:
        env.model.actuator_forcerange[ids] = saved
        env.model.actuator_forcelimited[ids] = saved_limited
        env.model.actuator_ctrllimited[ids] = saved_ctrl_limited
        env.close_gripper()
    force, travel, weakest = np.array(samples).T
    if np.any(weakest <= 0):
        raise PhysicsError(f"the jaws do not both press object {obj_id} while squeezing; grasp it first")
    if np.ptp(travel) <= 0:
        raise PhysicsError(f"the fingers did not move between force levels {forces}; is object {obj_id} "
                           "between them?")
    slope = float(np.polyfit(travel, force, 1)[0])
    logger.debug("squeeze object %d: forces %s N, travel %s mm -> %.0f N/m", obj_id, np.round(force, 3),
                 np.round(travel * 1000, 4), slope)
    env.measurements.setdefault(obj_id, {})["stiffness"] = slope
    return slope

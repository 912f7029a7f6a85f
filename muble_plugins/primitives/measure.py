"""The readings of ``weigh`` and ``squeeze``: weight from the wrist force sensor, stiffness from squeezing.

Both read what the simulated hardware reports (sensor forces, finger pad positions), through the environment API
alone (``muble.core.environment.Environment``: ``wrist_wrench``, ``advance`` with a per-physics-step callback, the
pads' geoms and contacts); neither looks at the ground truth stored in the model. The primitives
(``muble_plugins.primitives.gripper``) check that there is something to measure and call these.
docs/physical_properties.md gives the physics and the accuracy measured.
"""
from __future__ import annotations

import logging

import mujoco
import numpy as np

from muble.core.environment import GRAVITY
from muble.core.errors import PhysicsError
from muble.core.object_physics import JAW_SQUARE

logger = logging.getLogger(__name__)

WEIGH_SETTLE = 0.6  # s of holding still before reading; see docs/environment.md for how it was chosen
WEIGH_WINDOW = 0.2  # s over which the force is averaged


def mean_wrist_force(env, window: float = WEIGH_WINDOW) -> np.ndarray:
    """Wrist force (world frame) averaged over ``window`` seconds while holding, sampled every physics step.

    A held object's jaw contacts chatter at a few hundred hertz: the jaw contact law sets
    their stiffness once per control step, and the Robotiq 85's linkage rings after each change, so the reading
    swings by up to ±0.4 N (±40 g) within a control period and averages out over it. Sampled once per control
    step, always at the same phase after the change, the mean is off by several grams (a 242.8 g glass reads
    +6.2 g); every physics step's reading averages the whole cycle."""
    total, count = np.zeros(3), 0

    def sample():
        nonlocal total, count
        total += env.wrist_wrench()[0]
        count += 1

    env.advance(window, on_physics=sample)
    return total / count


def weigh(env, settle: float = WEIGH_SETTLE, window: float = WEIGH_WINDOW, record: bool = True) -> float:
    """Weight in grams of what the hand holds: hold still, read the wrist force, subtract the tare, divide by g;
    recorded as the held object's measured weight (``env.measurements``) unless ``record`` is false.

    Needs a tare taken with the empty hand (``env.tare()``, before grasping).
    """
    if env.tare_force is None:
        raise PhysicsError("no tare: call env.tare() with the empty hand, before grasping, then weigh")
    env.hold(settle)
    force = mean_wrist_force(env, window)
    # Sign measured: a held load adds +z to the world-frame reading of this sensor.
    extra = force - env.tare_force
    grams = float(extra[2] / GRAVITY * 1000.0)
    if record and env.held_object is not None:
        env.measurements.setdefault(env.held_object, {})["weight"] = grams
    return grams


SQUEEZE_FORCES = (5.0, 10.0, 15.0)  # N per pad: the actuators' force limit at each level, through the linkage
SQUEEZE_SETTLE = 0.5  # s at each force level before reading
SQUEEZE_WINDOW = 0.1  # s over which jaw force and finger position are averaged
# Still settling, the pads move, and the object's contact damping adds to (closing) or takes from (opening) the
# jaw force; a level read so is off the object's force-depth line. The Robotiq 85's damped linkage relaxes for
# ~2 s from the grasp's ~20 N to the first level (read after 0.5 s: +4 to +8 % on the five-object scene, after
# 2 s: +1 to +2.6 %), so each level is read again, a window later, until the jaw force drifts by less than
# SQUEEZE_DRIFT of the level over a window, or SQUEEZE_SETTLE_MAX has passed. The Panda drifts by up to 2.3 % of
# the first level after 0.5 s: 1 % makes it wait too, and its errors shrink (five-object scene: -1.7..+2.7 % to
# -0.2..+1.6 %).
SQUEEZE_DRIFT = 0.01
SQUEEZE_SETTLE_MAX = 3.0  # s


def pad_centres(env) -> np.ndarray:
    """World positions (2, 3) of the left and right pad centres: the mean position of each side's pad geoms."""
    side, xpos = env.pad_side, env.data.geom_xpos
    return np.array([xpos[side == s].mean(axis=0) for s in (1, 2)])


def closing_axes(env) -> np.ndarray:
    """Unit vectors (2, 3) in which the left and right pads close: from each side's pad centre towards the other's.
    Any two-sided gripper has pads; its finger joints may slide (Panda) or turn (Robotiq 85's linkage), so no
    joint axis says which way a pad moves."""
    axes = env.closing_axes()  # the jaw law's own directions
    if axes is None:
        raise PhysicsError("the two pads' centres coincide: no closing direction to squeeze along")
    return axes


def jaw_forces(env, obj_id: int, axes: np.ndarray | None = None) -> np.ndarray:
    """Force (N) with which ``obj_id`` pushes back on each jaw (left, right), against each side's closing axis
    (default: ``closing_axes`` now): the contact forces between the object and every geom of that finger, as a
    force sensor in the finger reads."""
    axes = closing_axes(env) if axes is None else axes
    out = np.zeros(2)
    for k, _, force in env.finger_contacts(obj_id):
        out[k] += float(force @ axes[k])
    return out


def _hand_frame(env) -> tuple[np.ndarray, np.ndarray]:
    """Position and rotation matrix of the hand body, the fingers' common base (what their encoders measure from)."""
    hand = env.model.body(env.names.hand_body).id
    return env.data.xpos[hand], env.data.xmat[hand].reshape(3, 3)


def _pad_bodies(env) -> np.ndarray:
    """Body of each side's (first) pad geom: the link whose motion the pad follows."""
    return np.array([env.model.geom_bodyid[np.flatnonzero(env.pad_side == s)[0]] for s in (1, 2)])


def pressure_points(env, obj_id: int) -> np.ndarray:
    """Where (world, (2, 3)) ``obj_id`` presses on each jaw: the contact points on that finger's geoms, weighted
    by their normal force; a side without contact gives its pad centre."""
    weighted, total = np.zeros((2, 3)), np.zeros(2)
    for k, contact, force in env.finger_contacts(obj_id):
        weighted[k] += np.linalg.norm(force) * contact.pos
        total[k] += np.linalg.norm(force)
    out = pad_centres(env)
    pressed = total > 0
    out[pressed] = weighted[pressed] / total[pressed, None]
    return out


def deepest_points(env, obj_id: int) -> np.ndarray:
    """Where (world, (2, 3)) ``obj_id`` is pressed deepest into each jaw along its closing axis: the contact of
    that finger's geoms with the largest depth / cos (cos: between its normal and the closing axis, at least
    ``muble.core.object_physics.JAW_SQUARE``), the penetration the jaw law presses with; a side without such a
    contact gives its pad centre."""
    axes = closing_axes(env)
    out, depth = pad_centres(env), np.zeros(2)
    for k, contact, force in env.finger_contacts(obj_id):
        norm = np.linalg.norm(force)
        cos = float(force @ axes[k]) / norm if norm > 0 else 1.0
        if cos >= JAW_SQUARE and -contact.dist / cos > depth[k]:
            depth[k], out[k] = -contact.dist / cos, contact.pos
    return out


def _on_pad_bodies(env, points: np.ndarray) -> np.ndarray:
    """World points (2, 3), one per side, in the frame of that side's pad body."""
    bodies = _pad_bodies(env)
    xpos, xmat = env.data.xpos[bodies], env.data.xmat[bodies].reshape(2, 3, 3)
    return np.einsum("kij,ki->kj", xmat, points - xpos)


def finger_closure(env, hand_axes: np.ndarray | None = None, pad_points: np.ndarray | None = None) -> np.ndarray:
    """Position (m) of a point on each side's pad along that side's closing axis, both in the hand's frame
    (default axes: ``closing_axes`` now). Only its changes mean anything: how far each pad has closed on the
    hand, as the fingers' encoders would say, whatever the arm does meanwhile. ``pad_points`` (2, 3) are points
    fixed on each side's pad body, in its frame (default: the pad centres now): where the object presses, so that
    a pad that tilts under the load (a linkage's compliance) is read where it sinks in. Recomputes the kinematics
    first: after a physics step the body poses are those at its start, the joint positions those at its end."""
    model, data = env.model, env.data
    mujoco.mj_kinematics(model, data)
    pos, rot = _hand_frame(env)
    hand_axes = closing_axes(env) @ rot if hand_axes is None else hand_axes
    if pad_points is None:
        points = pad_centres(env)
    else:
        bodies = _pad_bodies(env)
        points = data.xpos[bodies] + np.einsum("kij,kj->ki", data.xmat[bodies].reshape(2, 3, 3), pad_points)
    return np.einsum("ij,ij->i", (points - pos) @ rot, hand_axes)


def _pad_poses(env) -> tuple[np.ndarray, np.ndarray]:
    """Position (2, 3) and rotation (2, 3, 3) of each side's pad body in the hand's frame, as the fingers' encoders
    would give them. Recomputes the kinematics first (see ``finger_closure``)."""
    mujoco.mj_kinematics(env.model, env.data)
    pos, rot = _hand_frame(env)
    bodies = _pad_bodies(env)
    return ((env.data.xpos[bodies] - pos) @ rot,
            np.einsum("ji,kjl->kil", rot, env.data.xmat[bodies].reshape(2, 3, 3)))


def jaw_travel(pad_pos: np.ndarray, pad_rot: np.ndarray, points: np.ndarray, hand_axes: np.ndarray) -> np.ndarray:
    """How far (m) each side's pad has closed at each force level, read where the object presses it deepest.

    ``pad_pos`` (L, 2, 3) and ``pad_rot`` (L, 2, 3, 3) are the pad bodies' poses in the hand's frame at each of L
    levels, ``points`` (L, 2, 3) the deepest contact on each pad at that level, in the pad's frame, ``hand_axes``
    (2, 3) the closing axes in the hand's frame. The jaw law presses with the object's stiffness times the
    penetration of each jaw's deepest point; on a pad that tilts as it is loaded (a linkage's give) the points
    of a pad close by different amounts, and which point is deepest can change from level to level. So the travel
    from one level to the next is read at the point midway between the two levels' deepest points, and the
    travels add up: (L, 2), the first level's at its own deepest point."""
    def closure(level, pts):
        return np.einsum("kj,kj->k", pad_pos[level] + np.einsum("kij,kj->ki", pad_rot[level], pts), hand_axes)

    out = [closure(0, points[0])]
    for j in range(1, len(points)):
        mid = 0.5 * (points[j - 1] + points[j])
        out.append(out[-1] + closure(j, mid) - closure(j - 1, mid))
    return np.array(out)


def _dense(model, data, values, rownnz, rowadr, colind, nrow: int) -> np.ndarray:
    out = np.zeros((nrow, model.nv))
    if nrow:
        mujoco.mju_sparse2dense(out, values, rownnz[:nrow], rowadr[:nrow], colind)
    return out


def pad_transmission(env) -> float:
    """Metres the pads close (mean of the two sides, along ``closing_axes``) per unit of finger actuator travel,
    both actuators driven alike: by virtual work, an actuator force f presses each pad with f divided by this.
    1 for the Panda's slide fingers; a linkage (Robotiq 85) has a lever, so its drive's N m are not pad newtons.
    The fingers' free motion is what the equality constraints on their joints (a four-bar's coupling) allow."""
    model, data = env.model, env.data
    dofs = np.array([model.jnt_dofadr[model.joint(j).id] for j in env.names.gripper_joints])
    nefc = data.nefc
    if mujoco.mj_isSparse(model):
        efc = _dense(model, data, data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr, data.efc_J_colind, nefc)
    else:
        efc = data.efc_J[:nefc * model.nv].reshape(nefc, model.nv)
    coupling = efc[data.efc_type[:nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY][:, dofs]
    coupling = coupling[np.any(coupling != 0, axis=1)]
    # free finger motions: the null space of the coupling constraints
    if len(coupling):
        _, sv, vt = np.linalg.svd(coupling)
        rank = int(np.sum(sv > 1e-9 * sv.max()))
        free = vt[rank:].T
    else:
        free = np.eye(len(dofs))
    moment = _dense(model, data, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind,
                    model.nu)[env.gripper_actuator_ids][:, dofs]
    sign = np.sign(env.gripper_closed_ctrl - env.gripper_open_ctrl)
    sign[sign == 0] = 1.0
    coeffs = np.linalg.lstsq(moment @ free, sign, rcond=None)[0]
    velocity = np.zeros(model.nv)
    velocity[dofs] = free @ coeffs  # every actuator closing at unit speed
    axes = closing_axes(env)
    jacp = np.zeros((3, model.nv))
    closing = 0.0
    for side in (1, 2):
        pads = np.flatnonzero(env.pad_side == side)
        for g in pads:
            mujoco.mj_jac(model, data, jacp, None, data.geom_xpos[g], model.geom_bodyid[g])
            closing += float(jacp @ velocity @ axes[side - 1]) / len(pads)
    return 0.5 * closing


def _drift(force: np.ndarray) -> float:
    """How much ``force``, sampled every control step over one window, changes over a whole window."""
    if len(force) < 2:
        return 0.0
    return float(abs(force[-1] - force[0]) * len(force) / (len(force) - 1))


def squeeze(env, obj_id: int | None = None, forces=SQUEEZE_FORCES, settle: float = SQUEEZE_SETTLE,
            window: float = SQUEEZE_WINDOW) -> float:
    """Stiffness (N/m) of the object between the fingers (default: the one in the hand).

    At each force level the finger actuators are limited to the force that presses each pad with that many newtons
    (``pad_transmission``) and commanded closed; after ``settle`` s, and until the jaw force stops drifting
    (``SQUEEZE_DRIFT``), the jaw forces and the pads' positions are averaged over ``window`` s. Both are read from
    the pads, which every two-sided gripper has, along each side's closing axis (``closing_axes``) in the hand's
    frame: the travel where the object presses each pad deepest (``deepest_points``, ``jaw_travel``: a linkage's
    pads tilt under load). The stiffness is the least-squares slope of the mean jaw force against the mean pad
    travel: force per metre a jaw penetrates the object.
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
    # closing axes as grasped, fixed in the hand, so that each pad's travel is a projection on one line
    hand_axes = closing_axes(env) @ _hand_frame(env)[1]
    transmission = pad_transmission(env)
    if not transmission > 0:
        raise PhysicsError(f"the finger actuators do not close the pads (transmission {transmission:g} m/unit)")
    levels, poses, rotations, points = [], [], [], []
    window_forces, window_pos, window_rot = [], [], []

    def read(_k):
        axes = hand_axes @ _hand_frame(env)[1].T  # the hand's pose when these contacts were found
        window_forces.append(jaw_forces(env, obj_id, axes))
        pos, rot = _pad_poses(env)
        window_pos.append(pos)
        window_rot.append(rot)

    try:
        env.model.actuator_ctrllimited[ids] = 0
        for level in forces:
            env.model.actuator_forcerange[ids] = (-level * transmission, level * transmission)
            env.model.actuator_forcelimited[ids] = 1
            env.close_gripper()
            env.data.ctrl[ids] = push
            env.hold(settle)
            waited = settle
            while True:
                window_forces.clear()
                window_pos.clear()
                window_rot.clear()
                env.advance(window, on_control=read)
                waited += window
                drift = _drift(np.array(window_forces).mean(axis=1))
                if drift <= SQUEEZE_DRIFT * level or waited >= SQUEEZE_SETTLE_MAX - 1e-9:
                    break
            force_l, force_r = np.mean(window_forces, axis=0)
            levels.append((0.5 * (force_l + force_r), min(force_l, force_r)))
            poses.append(np.mean(window_pos, axis=0))
            rotations.append(np.mean(window_rot, axis=0))
            points.append(_on_pad_bodies(env, deepest_points(env, obj_id)))  # after the window's last step
            logger.debug("squeeze level %.3g after %.1f s: jaw forces %.3f %.3f N (drift %.3f N a window), "
                         "deepest points on the pads %s mm", level, waited, force_l, force_r, drift,
                         np.round(points[-1] * 1000, 2).tolist())
    finally:
        env.model.actuator_forcerange[ids] = saved
        env.model.actuator_forcelimited[ids] = saved_limited
        env.model.actuator_ctrllimited[ids] = saved_ctrl_limited
        env.close_gripper()
    travels = jaw_travel(np.array(poses), np.array(rotations), np.array(points), hand_axes)
    samples = [(f, t.mean(), w) for (f, w), t in zip(levels, travels)]
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

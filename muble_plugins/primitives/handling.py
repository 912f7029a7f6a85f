"""The readings of ``push``, ``balance`` and ``shake``, measurements by handling an object: friction from pushing it
along the table, its centre of mass from holding it still in the air, loose contents from shaking it.

Like ``muble_plugins.primitives.measure`` (weight, stiffness), each reads what the simulated hardware reports,
through the environment API alone (``muble.core.environment.Environment``): the wrist force/torque sensor, the
arm's own state (its joints, hence its hand's pose and acceleration) and the object's pose as a camera sees it;
none looks at the object's modelled values. The wrist is read as ``Environment.load_wrench`` gives it: less the
hand's own weight from the robot's model of its hand (mass and centre of mass at the fingers' current positions),
the tool compensation of a real force/torque sensor; an averaged reading with the empty hand would do the same,
but the fingers then stand elsewhere, and on the Panda that moves the hand's centre of mass by millimetres. The
primitives (``muble_plugins.primitives.probing``) plan the motions and call these. See
docs/physical_properties.md for the physics and the accuracy measured.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np

from muble.core.environment import GRAVITY
from muble.core.errors import PhysicsError
from muble.stage.geometry import tilt_deg

logger = logging.getLogger(__name__)

BALANCE_SETTLE = 0.6  # s of holding still before reading, as for weighing (``measure.WEIGH_SETTLE``)
BALANCE_WINDOW = 0.2  # s over which force and torque are averaged, at every physics step
# Least load (N) on the wrist for a reading: below it the lever arm is torque noise over almost nothing.
MIN_LOAD = 0.1
# Weight of the guess that the centre of mass is halfway up the object, against the readings' equations (metres
# against metres): it settles only the height that the readings leave open (all of them upright), and moves a
# height they fix by 1 % of the guess's error.
HEIGHT_PRIOR = 0.01
# Peak force (N) left on the wrist once the rigid response of the hand and the held body to the shaking is taken
# off: a solid or an empty container leaves a few hundredths of a newton, a ball of 10 g or more rattling inside
# several tenths (docs/physical_properties.md has the figures).
RATTLE_FORCE = 0.2
# A noisy wrist sensor (``Environment.sensor_noise``) scatters every sample by its white noise, and a shake reads
# several hundred of them on three axes: their largest is about 3.7 times the noise's spread. So a peak counts only
# above this many times the sensor's stated white noise as well (about one solid shake in 2,000 reads more).
RATTLE_NOISE_SIGMAS = 5.0


def _held(env) -> int:
    if env.held_object is None:
        raise PhysicsError("nothing in the hand: grasp an object first")
    return env.held_object


# ---------------------------------------------------------------------------------------------- centre of mass
def balance(env, tilts=(), settle: float = BALANCE_SETTLE, window: float = BALANCE_WINDOW) -> np.ndarray:
    """Horizontal position (m, (2,)) of the held object's centre of mass in its own frame, off its origin (the
    centre of its base): the object held still in the air, the wrist torque divided by the weight it carries; read
    where the hand holds it now and again after each of ``tilts`` (trajectories that tilt the hand in place).

    The load's torque about the sensor's site is ``r × W`` with ``W`` the weight (up) and ``r`` from the site to
    the centre of mass, so ``r_x = -τ_y / W``, ``r_y = τ_x / W``: each reading gives the vertical line through the
    centre of mass, two equations on its three coordinates in the object's frame. An object held upright gives the
    horizontal ones whatever its height. One held leaning (a bowl pinched by its rim may tip over in the hand)
    leaves its centre of mass's place along that line open, and that moves the horizontal offset: a second reading
    with the hand tilted sees the line at another angle in the object's frame. The result is the least-squares
    point of all lines, with a weak pull towards half the object's height where they leave the height open."""
    obj_id = _held(env)
    rows, values = [], []

    def read():
        env.hold(settle)
        force, torque, site, count = np.zeros(3), np.zeros(3), np.zeros(3), 0

        def sample():
            nonlocal force, torque, site, count
            f, t = env.load_wrench()
            force += f
            torque += t
            site += env.data.site_xpos[env.ft_site_id]
            count += 1

        env.advance(window, on_physics=sample)
        force, torque, site = force / count, torque / count, site / count
        weight = float(force[2])
        if weight < MIN_LOAD:
            raise PhysicsError(f"the hand carries {weight:.3f} N: lift object {obj_id} off its support first")
        line = site[:2] + np.array([-torque[1], torque[0]]) / weight
        pose = env.object_pose(obj_id)
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, pose.quat)
        rot = rot.reshape(3, 3)
        rows.append(rot[:2, :])  # horizontal world position of a point c of the object: pose.pos + rot @ c
        values.append(line - pose.pos[:2])
        logger.debug("balance object %d: load %.3f N, leaning %.1f deg", obj_id, weight,
                     tilt_deg(pose.quat))

    read()
    for trajectory in tilts:
        track(env, trajectory, lambda: None)
        read()
    height = 0.5 * float(env.object_models[obj_id].extents[2])  # its own height, however it leans
    rows.append(HEIGHT_PRIOR * np.array([[0.0, 0.0, 1.0]]))
    values.append(HEIGHT_PRIOR * np.array([height]))
    centre = np.linalg.lstsq(np.vstack(rows), np.concatenate(values), rcond=None)[0]
    logger.debug("balance object %d: centre of mass %s mm in its frame (%d readings)", obj_id,
                 np.round(centre * 1000, 2).tolist(), len(tilts) + 1)
    env.measurements.setdefault(obj_id, {})["com_offset"] = [float(v) for v in centre[:2] * 1000.0]
    return centre[:2]


# ---------------------------------------------------------------------------------------------------- friction
def track(env, trajectory, on_physics) -> None:
    """Follow a joint ``trajectory`` as ``env.follow`` does (set-points with velocity feed-forward at the control
    rate), calling ``on_physics()`` after every physics step."""
    period = env.control_dt
    t = trajectory.t[0] + np.arange(int(np.ceil(trajectory.duration / period)) + 1) * period
    q = np.stack([np.interp(t, trajectory.t, trajectory.q[:, j]) for j in range(trajectory.q.shape[1])], 1)
    qd = np.gradient(q, period, axis=0) if len(t) > 1 else np.zeros_like(q)
    qd[-1] = 0.0

    def command(k):
        k = min(k, len(q) - 1)
        env.set_arm_target(q[k], qd[k])

    env.advance(len(q) * period, on_control=command, on_physics=on_physics)


# rad any arm joint may end a stroke behind its planned configuration: more, and the arm was held back (an object
# of high friction can jam: its drag turns the hand on its weak wrist joints, the leading edge digs into the table,
# the table presses harder and the drag grows), so the stroke was no steady slide.
PUSH_LAG = 0.05


@dataclass
class PushReading:
    """What pushing found: the friction coefficient (NaN without a steady slide), the mean normal force the table
    carried (N), how many samples were read, and whether the arm fell behind every stroke (``PUSH_LAG``) or short
    of its steady stretch: a stroke it fell behind is left out of the reading."""

    friction: float
    normal: float
    samples: int
    stalled: bool = False


def push(env, strokes, steady: tuple[float, float], weight_g: float | None = None) -> PushReading:
    """Friction coefficient between the held object and the table: the object, held where it stands, is pushed
    along the table by each of ``strokes`` (``(trajectory, direction)``: a straight move of the hand, the unit
    horizontal direction it travels), sampled at every physics step while the hand has travelled between
    ``steady[0]`` and ``steady[1]`` metres (the steady middle of the stroke, past its speeding up and before its
    slowing down).

    At steady speed the arm pulls the hand along with the table's friction on the object, ``F·d``, and holds up
    ``F_z`` of the object's weight ``W`` (``weight_g``, else the weight measured in this episode), so the table carries
    ``N = W - F_z`` (more than ``W`` where the hand presses down). The coefficient is ``mean(F·d) / mean(N)`` over
    the steady samples of the strokes the arm kept up with (``PUSH_LAG``). Held in the hand, the object slides as
    fast as the hand, never faster or by fits and starts, and cannot tip: pushed by a finger it hops on its stiff
    contacts at every speed, and its friction falls short of the coefficient while it does.

    Unlike the other readings, this one records nothing in ``env.measurements``: whether the push counts (the
    object still in the hand, a steady slide read) is the ``push`` primitive's to decide, and it records the
    coefficient only then; a push that lost the object leaves no reading behind."""
    obj_id = _held(env)
    grams = weight_g if weight_g is not None else env.measurements.get(obj_id, {}).get("weight")
    if grams is None:
        raise PhysicsError(f"object {obj_id} has no measured weight: weigh it before pushing it")
    weight = float(grams) / 1000.0 * GRAVITY
    ee_site = env.model.site(env.ee_site).id
    along, normal = [], []
    stalled = 0
    for trajectory, direction in strokes:
        direction = np.asarray(direction, dtype=float)
        start = env.ee_pose().pos.copy()
        stroke_along, stroke_normal, farthest = [], [], [0.0]

        def sample(direction=direction, start=start, farthest=farthest, stroke_along=stroke_along,
                   stroke_normal=stroke_normal):
            travel = float((env.data.site_xpos[ee_site] - start) @ direction)
            farthest[0] = max(farthest[0], travel)
            if steady[0] <= travel <= steady[1]:
                force = env.load_wrench()[0]
                stroke_along.append(float(force @ direction))
                stroke_normal.append(weight - float(force[2]))

        track(env, trajectory, sample)
        lag = float(np.max(np.abs(env.arm_q() - trajectory.q[-1])))
        if lag > PUSH_LAG or farthest[0] < steady[1]:
            stalled += 1  # its samples are no steady slide
            logger.debug("push object %d: a stroke stalled (joint lag %.3f rad, reached %.3f m)", obj_id, lag,
                         farthest[0])
            continue
        along += stroke_along
        normal += stroke_normal
    if not along:
        return PushReading(float("nan"), 0.0, 0, stalled == len(strokes) and stalled > 0)
    table = float(np.mean(normal))
    friction = float(np.mean(along)) / table if table > 0 else float("nan")
    logger.debug("push object %d: %d samples, friction force %.3f N, normal force %.3f N -> %.3f", obj_id,
                 len(along), np.mean(along), table, friction)
    return PushReading(friction, table, len(along))


# ------------------------------------------------------------------------------------------------ loose contents
@dataclass
class ShakeReading:
    """What shaking found: whether something rattles inside, and the largest force (N) on the wrist that the held
    body's rigid motion does not explain."""

    rattles: bool
    peak: float


def shake(env, ends: tuple[np.ndarray, np.ndarray], period: float, cycles: int) -> ShakeReading:
    """Shake the held object: the arm swings ``cycles`` times between the joint configurations ``ends`` (the hand
    at either end of a short horizontal line, the middle where it is now), ``period`` seconds a swing, easing in
    and out over one period; then whether it rattles.

    A rigid load (a solid or an empty container) makes the wrist force a linear function of the spatial
    accelerations of the hand and of the held body (their masses and inertias; the held body rocks a little on its
    grasp, so its own acceleration, which a camera tracking it sees, counts too) plus the constant weight. Loose
    contents hit the container's walls out of step with both: force spikes that no such function explains. So the
    force along each axis, sampled at every physics step, is fitted by least squares to those twelve acceleration
    components and a constant, and the largest residual is the reading: ``rattles`` when above
    ``RATTLE_FORCE`` (and, for a noisy sensor, above ``RATTLE_NOISE_SIGMAS`` times its white noise)."""
    obj_id = _held(env)
    q0 = env.arm_q()
    half = 0.5 * (np.asarray(ends[0], dtype=float) - np.asarray(ends[1], dtype=float))
    omega = 2.0 * np.pi / period
    total = period * (cycles + 1)  # a period of easing in and out on top of the full swings
    forces, accelerations = [], []
    acceleration, held = np.zeros(6), np.zeros(6)

    def command(k):
        t = (k + 1) * env.control_dt
        if t >= total:
            env.set_arm_target(q0, np.zeros_like(q0))
            return
        ease = min(1.0, t / period, (total - t) / period)
        env.set_arm_target(q0 + ease * np.sin(omega * t) * half, ease * omega * np.cos(omega * t) * half)

    body = env.model.body(env.names.objects[obj_id]).id
    ee_site = env.model.site(env.ee_site).id

    def sample():
        mujoco.mj_objectAcceleration(env.model, env.data, mujoco.mjtObj.mjOBJ_SITE, ee_site, acceleration, 0)
        mujoco.mj_objectAcceleration(env.model, env.data, mujoco.mjtObj.mjOBJ_BODY, body, held, 0)
        forces.append(env.wrist_wrench()[0].copy())
        accelerations.append(np.concatenate([acceleration, held]))

    env.advance(total + period / 2, on_control=command, on_physics=sample)
    forces, design = np.array(forces), np.column_stack([np.array(accelerations), np.ones(len(forces))])
    fit = np.linalg.lstsq(design, forces, rcond=None)[0]
    peak = float(np.abs(forces - design @ fit).max())
    rattles = peak > max(RATTLE_FORCE, RATTLE_NOISE_SIGMAS * env.sensor_noise.force_white_n)
    logger.debug("shake object %d: largest unexplained wrist force %.3f N -> %s", obj_id, peak,
                 "rattles" if rattles else "solid")
    # Not recorded here: the primitive records it once it knows the object stayed in the hand throughout.
    return ShakeReading(rattles, peak)

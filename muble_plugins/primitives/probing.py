"""Primitives that measure hidden physical properties by handling the held object: ``push`` (its friction
coefficient on the table), ``balance`` (its centre of mass) and ``shake`` (whether loose contents rattle inside).

Each plans its motion here (straight hand moves, checked against the collision world with the object carried) and
takes its reading with ``muble_plugins.primitives.handling`` (``push``, ``balance``, ``shake``), which reads the
wrist sensor through the environment API. docs/physical_properties.md gives the physics and the accuracy measured.
"""
from __future__ import annotations

import logging

import mujoco
import numpy as np

from muble import ActionResult, Param, PlanningError, Pose, PoseGoal, PrimitiveAction, SceneGraph, get_registry
from muble.core import physical_properties
from muble.core.observation import MEASURED_EXTRA
from muble.core.params import argument
from muble.core.symbolic import ArmState
from muble.stage.geometry import geom_world_vertices, tilt_deg
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import handling
from muble_plugins.primitives import measure as measuring
from muble_plugins.primitives import tolerances as tol
from muble_plugins.primitives.common import ATTEMPT, rotated
from muble_plugins.primitives.gripper import GRIPPER_SETTLE, close_on_object

logger = logging.getLogger(__name__)

# Horizontal directions (world x, y) tried in turn where a call names none: sideways first, along the table's
# width, where the arm's reach changes least; then towards and away from the robot; then the diagonals.
DIRECTIONS = ((0.0, 1.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 0.0),
              *((sx * 0.7071, sy * 0.7071) for sx in (1.0, -1.0) for sy in (1.0, -1.0)))
DIRECTION = Param("direction", "vector", length=2, low=-1.0, high=1.0,
                  doc="horizontal (x, y), world frame; default: the first of DIRECTIONS the arm can move along")

PUSH_DISTANCE = 0.08  # m the object is pushed, there and back again
PUSH_SPEED = 0.05  # m/s of the hand, steady in the middle of each stroke
# The straight-line planner eases in and out over its first and last five waypoints; with PUSH_STEP between them
# the hand is at its steady speed from about 1.5 cm into a stroke to 1 cm before its end. The wrist is read in
# between, PUSH_SPEED_UP after the start and PUSH_SLOW_DOWN before the end.
PUSH_STEP = 0.002
PUSH_SPEED_UP = 0.02
PUSH_SLOW_DOWN = 0.015
# m the held object is lifted off the table to be weighed first, when its weight is not measured in this episode;
# it stays in the hand and is set down where it stood.
PUSH_WEIGH_LIFT = 0.015
# A retried push (``attempt`` k) starts from the k-th of the directions, and goes this factor slower and shorter
# per attempt, down to the least speed and distance: the arm falls behind a push on a high-friction object and
# keeps up with a slower one, and a shorter stroke fits between close neighbours.
PUSH_RETRY_SLOWER = 0.8

SHAKE_AMPLITUDE = 0.02  # m either side of where the hand holds the object
SHAKE_PERIOD = 0.5  # s a swing: 2 Hz, 3 m/s² at the ends of 2 cm, enough to roll a loose ball from wall to wall
SHAKE_CYCLES = 4
# Points along the swing checked against the collision world, and the largest joint change (rad) from one end to
# the other that is still the short straight swing it is meant to be (not a jump to another arm branch).
SHAKE_CHECKS = 9
SHAKE_MAX_JOINT_CHANGE = 0.5


def _directions(given) -> list[np.ndarray]:
    """Unit horizontal directions (3,) to try: the one given, or ``DIRECTIONS``."""
    pairs = [given] if given is not None else DIRECTIONS
    out = []
    for x, y in pairs:
        d = np.array([float(x), float(y), 0.0])
        norm = float(np.linalg.norm(d))
        if norm < 1e-6:
            raise PlanningError("the direction (0, 0) has no heading: give a horizontal direction (x, y)")
        out.append(d / norm)
    return out


def _lifted(env, action: str) -> tuple[int | None, ActionResult | None]:
    """The held object, if it hangs free in the hand (lifted off everything); else the failed result."""
    held = env.held_object
    if held is None:
        return None, ActionResult(False, failure_reason=f"nothing in the hand to {action}: pick an object up first")
    if not env.is_lifted(held):
        return None, ActionResult(False, failure_reason=f"object {held} still touches its support: lift it first")
    return held, None


class Push(PrimitiveAction):
    """Friction coefficient (no unit) of the held object on the table: held where it stands on the table, it is
    pushed ``distance`` along ``direction`` at a slow steady ``speed`` and back again; the wrist force along the
    push divided by the force the table carries (the object's weight less what the hand holds up). The weight is
    the one measured in this episode (``weigh``); without one, the object is first lifted ``PUSH_WEIGH_LIFT`` in
    the hand, read still as ``weigh`` reads it, and set down where it stood (that reading serves the push only).
    ``attempt`` k (a retry) starts from the k-th direction and pushes ``PUSH_RETRY_SLOWER`` slower and shorter per
    attempt."""

    params = (DIRECTION,
              Param("distance", "number", low=0.05, high=0.15, default=PUSH_DISTANCE, doc="m, there and back"),
              Param("speed", "number", low=0.03, high=0.1, default=PUSH_SPEED,
                    doc="m/s, steady in the middle of each stroke"),
              ATTEMPT)
    measures = "friction"
    measure_unit = ""
    reading = staticmethod(handling.push)

    def execute(self, env) -> ActionResult:
        held = env.held_object
        if held is None:
            return ActionResult(False, failure_reason="nothing in the hand to push: grasp an object that stands on "
                                                      "the table first")
        problem = _settle_on_table(env, held)
        if problem:
            return ActionResult(False, failure_reason=problem)
        grams = env.measurements.get(held, {}).get("weight")
        if grams is None:
            grams, problem = _weigh_where_it_stands(env, held)
            if problem:
                return ActionResult(False, failure_reason=problem)
        attempt = int(argument(self, "attempt"))
        bounds = {p.name: p.low for p in self.params}
        retry = PUSH_RETRY_SLOWER ** attempt
        distance = max(bounds["distance"], float(argument(self, "distance")) * retry)
        speed = max(bounds["speed"], float(argument(self, "speed")) * retry)
        direction, strokes = self._plan(env, distance, speed, attempt)
        reading = handling.push(env, strokes, (PUSH_SPEED_UP, distance - PUSH_SLOW_DOWN), grams)
        info = {"object": held, "direction": direction[:2].tolist(), "normal_force": reading.normal,
                "samples": reading.samples}
        if env.held_object != held:
            return ActionResult(False, info=info, failure_reason=f"object {held} slipped out of the hand while pushed")
        if reading.stalled:
            return ActionResult(False, info=info, failure_reason=f"object {held} stuck on the table: the arm fell "
                                                                 "behind the push, so no steady slide was read")
        if not np.isfinite(reading.friction) or reading.normal <= 0:
            return ActionResult(False, info=info, failure_reason=f"object {held} did not slide on the table while "
                                                                 "pushed (it was lifted off it)")
        # Recorded only now that the push is known to have read a steady slide of the object still in the hand: a
        # push that failed leaves no reading behind.
        env.measurements.setdefault(held, {})[self.measures] = reading.friction
        return ActionResult(True, measurement=reading.friction, info=info)

    def _plan(self, env, distance: float, speed: float, attempt: int = 0):
        """The first direction the held object can be pushed along and back: (direction, strokes)."""
        world = env.collision_world()  # carrying the held object
        world.allow_contact([env.table().body])  # it slides on the table, the fingers close above it
        line = get_registry().create("planner", "straight_line",
                                     {"speed": speed, "step": PUSH_STEP, "max_distance": distance + 0.01})
        start_q, pose = env.arm_q(), env.ee_pose()
        reasons = []
        for direction in rotated(_directions(self.arguments.get("direction")), attempt):
            there = PoseGoal(Pose(pose.pos + distance * direction, pose.quat), *tol.VELOCITY)
            back = PoseGoal(pose, *tol.VELOCITY)
            try:
                out = line.plan(start_q, there, world)
                home = line.plan(out.q[-1], back, world)
            except PlanningError as e:
                reasons.append(f"{direction[:2].round(2).tolist()}: {e}")
                continue
            return direction, [(out, direction), (home, -direction)]
        raise PlanningError(f"the held object cannot be pushed {distance:.2f} m along the table in any direction "
                            f"tried: {'; '.join(reasons[:3])}")

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The held object's friction coefficient is known (pushed there and back, it ends where it stood)."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or hand.raised:
            return ActionResult(False, failure_reason="pushing needs a grasped object standing on the table")
        friction = physical_properties.friction_of(held)
        if friction is None:
            return ActionResult(False, failure_reason=f"object {held.id} has no friction coefficient to measure")
        held.extra[MEASURED_EXTRA[self.measures]] = friction  # as the physical world's scene graph records it
        return ActionResult(True, measurement=friction)


# m above the table within which a held object is set down on it before it is pushed: a gripper may lift what it
# grasps as its pads close (by a fraction of a millimetre, or by a centimetre where a linkage gripper's pads slide
# up a tapered side), and a push that weighs first leaves it PUSH_WEIGH_LIFT up where setting it down failed;
# PUSH_PRESS further down makes sure it rests (the hand's servos give a little, so it then presses with a newton
# or so), reached within PUSH_SET_DOWN_TOLERANCE.
PUSH_SET_DOWN = 0.02
PUSH_PRESS = 0.0002
PUSH_PRESSES = (PUSH_PRESS, 5 * PUSH_PRESS, 15 * PUSH_PRESS)
PUSH_SET_DOWN_TOLERANCE = (0.0001, 0.01)


def _settle_on_table(env, obj_id: int) -> str | None:
    """Set the held object down on the table if it hangs just above it (``PUSH_SET_DOWN``); why it cannot be
    pushed along the table, or None."""
    problem = _not_on_table(env, obj_id)
    gap = _height_above_table(env, obj_id)
    if problem is None or not 0.0 < gap <= PUSH_SET_DOWN or _touches_other(env, obj_id):
        return problem
    world = env.collision_world()
    world.allow_contact([env.table().body])
    for press in PUSH_PRESSES:  # a stiff grip may keep it a hair above the table: press further the next time
        pose = env.ee_pose()
        down = PoseGoal(Pose(pose.pos - [0.0, 0.0, gap + press], pose.quat), *PUSH_SET_DOWN_TOLERANCE)
        trajectory = ctx.straight_line_planner(env).plan(env.arm_q(), down, world)
        env.follow(trajectory, settle=tol.STEP_SETTLE)
        problem = _not_on_table(env, obj_id)
        gap = _height_above_table(env, obj_id)
        if problem is None or not 0.0 < gap <= PUSH_SET_DOWN:
            return problem
    # Still held a hair above it: let go, so that it stands on the table, and grasp it again where it stands.
    env.open_gripper()
    env.hold(GRIPPER_SETTLE)
    if close_on_object(env) != obj_id:
        return f"object {obj_id} slipped out of the hand while it was set down on the table to be pushed"
    return _not_on_table(env, obj_id)


def _weigh_where_it_stands(env, obj_id: int) -> tuple[float | None, str | None]:
    """The held object's weight (g), read lifted ``PUSH_WEIGH_LIFT`` off the table and still, as ``weigh`` reads
    it (not recorded as a measurement of the episode), then set down where it stood: (grams, None), or (None, why
    not)."""
    world = env.collision_world()
    world.allow_contact([env.table().body])
    planner = ctx.straight_line_planner(env)
    pose = env.ee_pose()
    up = PoseGoal(Pose(pose.pos + [0.0, 0.0, PUSH_WEIGH_LIFT], pose.quat), *tol.FREE)
    env.follow(planner.plan(env.arm_q(), up, world), settle=tol.STEP_SETTLE)
    if env.held_object != obj_id or not env.is_lifted(obj_id):
        return None, f"object {obj_id} did not come off the table in the hand to be weighed before the push"
    grams = measuring.weigh(env, record=False)
    down = PoseGoal(Pose(pose.pos - [0.0, 0.0, PUSH_PRESS], pose.quat), *PUSH_SET_DOWN_TOLERANCE)
    env.follow(planner.plan(env.arm_q(), down, world), settle=tol.STEP_SETTLE)
    return grams, _settle_on_table(env, obj_id)


def _height_above_table(env, obj_id: int) -> float:
    """How far (m) the object's lowest point is above the table top, from its collision meshes as they stand."""
    m, d = env.model, env.data
    body = m.body(env.names.objects[obj_id]).id
    low = np.inf
    for g in np.flatnonzero((m.geom_bodyid == body) & (m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)):
        if m.geom_contype[g] or m.geom_conaffinity[g]:
            # The lowest vertex's z plus the geom's height, as before: adding is monotone, so the lowest sum
            # is the lowest z plus it, to the bit.
            low = min(low, float(geom_world_vertices(m, d, g)[:, 2].min()))
    return low - env.table().top_z


def _touches_other(env, obj_id: int) -> bool:
    m = env.model
    touching = ctx.touching_bodies(env, {m.body(env.names.objects[obj_id]).id})
    return any(i != obj_id and m.body(name).id in touching for i, name in env.names.objects.items())


def _not_on_table(env, obj_id: int) -> str | None:
    """Why the held object cannot be pushed along the table as it is, or None: it must stand on the table and
    touch nothing else but the hand."""
    m = env.model
    body = m.body(env.names.objects[obj_id]).id
    touching = ctx.touching_bodies(env, {body})
    table = env.table().body
    others = {i for i, name in env.names.objects.items() if i != obj_id and m.body(name).id in touching}
    if others:
        return f"object {obj_id} touches object(s) {sorted(others)}: it must stand on the table alone"
    if table not in touching:
        return f"object {obj_id} does not stand on the table: lower it onto the table first"
    return None


class _LiftedReading(PrimitiveAction):
    """A reading of the object hanging free in the hand: ``execute`` checks that one is lifted and hands it to
    ``read``; ``symbolic_effect`` checks the same in a scene graph and hands the object to ``known``."""

    action = ""  # the verb in failure reasons ("balance", "shake")

    def execute(self, env) -> ActionResult:
        held, failed = _lifted(env, self.action)
        return failed if failed else self.read(env, held)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or not hand.raised:
            return ActionResult(False, failure_reason=f"{self.action} needs a lifted object")
        return self.known(held)

    def read(self, env, held: int) -> ActionResult:
        raise NotImplementedError

    def known(self, held) -> ActionResult:
        raise NotImplementedError


class Balance(_LiftedReading):
    """Centre of mass of the lifted object: its horizontal offset [x, y] (mm, object frame) from the object's
    origin (the centre of its base), from the wrist torque held still divided by the weight it carries."""

    params = ()
    measures = "com_offset"
    measure_unit = "mm"
    action = "balance"
    reading = staticmethod(handling.balance)

    def read(self, env, held: int) -> ActionResult:
        tilts = _tilts(env, held)
        offset = handling.balance(env, tilts)
        return ActionResult(True, measurement=[round(float(v) * 1000.0, 2) for v in offset],
                            info={"object": held, "unit": "mm", "readings": 1 + len(tilts)})

    def known(self, held) -> ActionResult:
        """The lifted object's centre of mass is known: its ground truth (``physical_properties.COM_OFFSET``)."""
        offset = physical_properties.com_offset_mm(held)
        if offset is None:
            return ActionResult(False, failure_reason=f"object {held.id} has no centre of mass to measure")
        held.extra[MEASURED_EXTRA[self.measures]] = offset
        return ActionResult(True, measurement=offset)


# deg an object may lean in the hand and still be read once: its centre of mass's place along the vertical line
# then moves the horizontal offset by at most tan(3 deg) = 5 % of its distance from half the object's height.
BALANCE_LEAN = 3.0
# rad the hand tilts a leaning object for a second reading, about a horizontal axis through the grip site, tried in
# turn (about world x, then y, either way): enough to cross the first reading's line at a clear angle.
BALANCE_TILT = np.radians(25.0)
BALANCE_AXES = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


def _tilts(env, held: int) -> list:
    """Trajectories that tilt the hand in place and back again, for ``handling.balance``'s second reading of an
    object held leaning (``BALANCE_LEAN``); none for one held upright, or where no tilt can be planned."""
    quat = env.object_pose(held).quat
    lean = tilt_deg(quat)
    if lean <= BALANCE_LEAN:
        return []
    world = env.collision_world()  # carrying the held object
    line = ctx.straight_line_planner(env)
    start_q, pose = env.arm_q(), env.ee_pose()
    for x, y in BALANCE_AXES:
        half = BALANCE_TILT / 2
        tilt = np.array([np.cos(half), x * np.sin(half), y * np.sin(half), 0.0])
        try:
            there = line.plan(start_q, PoseGoal(Pose(pose.pos, _compose(tilt, pose.quat)), *tol.FREE), world)
            back = line.plan(there.q[-1], PoseGoal(pose, *tol.FREE), world)
        except PlanningError as e:
            logger.debug("balance: no tilt about (%g, %g) (%s)", x, y, e)
            continue
        return [there, back]
    logger.info("balance: object %d leans %.0f deg in the hand and cannot be tilted for a second reading", held,
                lean)
    return []


def _compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The quaternion (w, x, y, z) product ``a ⊗ b``: rotation ``b``, then ``a``."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


class Shake(_LiftedReading):
    """Whether something rattles inside the lifted object: the hand swings it ``cycles`` times ``amplitude``
    either side along ``direction``; loose contents hitting the walls are wrist force spikes that the rigid
    motion of a solid or an empty container does not make."""

    params = (DIRECTION,
              Param("amplitude", "number", low=0.01, high=0.04, default=SHAKE_AMPLITUDE, doc="m either side"),
              Param("period", "number", low=0.3, high=1.0, default=SHAKE_PERIOD, doc="s a swing"),
              Param("cycles", "int", low=2, high=8, default=SHAKE_CYCLES, doc="swings"))
    measures = "rattles"
    measure_unit = ""
    action = "shake"
    reading = staticmethod(handling.shake)

    def read(self, env, held: int) -> ActionResult:
        amplitude = float(argument(self, "amplitude"))
        direction, ends = self._ends(env, amplitude)
        reading = handling.shake(env, ends, float(argument(self, "period")), int(argument(self, "cycles")))
        info = {"object": held, "direction": direction[:2].tolist(), "peak_force": reading.peak}
        if env.held_object != held:
            return ActionResult(False, info=info, failure_reason=f"object {held} slipped out of the hand while "
                                                                 "shaken")
        env.measurements.setdefault(held, {})[self.measures] = bool(reading.rattles)
        return ActionResult(True, measurement=bool(reading.rattles), info=info)

    def _ends(self, env, amplitude: float):
        """The first direction the arm can swing the held object along: (direction, the two arm configurations
        at the ends of the swing)."""
        world = env.collision_world()  # carrying the held object
        q0, pose = env.arm_q(), env.ee_pose()
        reasons = []
        for direction in _directions(self.arguments.get("direction")):
            try:
                ends = tuple(world.local_inverse_kinematics(
                    PoseGoal(Pose(pose.pos + sign * amplitude * direction, pose.quat), *tol.VELOCITY), q0)
                    for sign in (1.0, -1.0))
            except PlanningError as e:
                reasons.append(f"{direction[:2].round(2).tolist()}: {e}")
                continue
            change = float(np.max(np.abs(ends[0] - ends[1])))
            swing = [q0 + s * 0.5 * (ends[0] - ends[1]) for s in np.linspace(-1.0, 1.0, SHAKE_CHECKS)]
            if change > SHAKE_MAX_JOINT_CHANGE:
                reasons.append(f"{direction[:2].round(2).tolist()}: the arm would turn a joint {change:.2f} rad")
            elif not all(world.is_valid(q) for q in swing):
                reasons.append(f"{direction[:2].round(2).tolist()}: the swing meets {list(world.last_contacts)[:2]}")
            else:
                return direction, ends
        raise PlanningError(f"the held object cannot be shaken {amplitude:.2f} m either way in any direction tried: "
                            f"{'; '.join(reasons[:3])}")

    def known(self, held) -> ActionResult:
        """Whether the lifted object holds loose contents (``physical_properties.CONTENTS``) is known."""
        rattles = physical_properties.rattles(held)
        held.extra[MEASURED_EXTRA[self.measures]] = rattles
        return ActionResult(True, measurement=rattles)

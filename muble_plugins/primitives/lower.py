"""The ``lower`` primitive: put the held object down on an object, on a table part or where it is, let it go and
leave it resting."""
from __future__ import annotations

import itertools
import logging

import numpy as np

from muble import ActionResult, JointGoal, Param, PlanningError, Pose, PoseGoal, PrimitiveAction, SceneGraph
from muble.core.observation import TOUCHING_TABLE
from muble.core.params import argument
from muble.core.symbolic import CARRIED_TO, RAISE_HEIGHT, ArmState, over, set_flag
from muble.stage.footprint import free_spot, height
from muble.stage.geometry import tilt_deg
from muble.stage.rest import at_rest, leaned_over
from muble.stage.table import part_box, parts_at
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import placement
from muble_plugins.primitives import tolerances as tol
from muble_plugins.primitives.grasping import below
from muble_plugins.primitives.common import (ATTEMPT, CARRY_TURNS, RELEASE_GAPS, checked_result, release_command,
                                             rotated)

logger = logging.getLogger(__name__)

# m a put-down without a target may shift the object to find a free place: 5 cm, so that it stays about where
# it was (the table parts it is in are kept too).
PUT_BACK_RADIUS = 0.05


class Lower(PrimitiveAction):
    """Put the held object down: on another object (scene id), on a table part, or where it is (no target).

    A table part gets the free place under the hand when there is one (``move`` chose it), else the free place
    nearest the part's centre; without a target the object goes straight down, or to the nearest free place
    within ``PUT_BACK_RADIUS`` in the same table parts. The object is released and left resting.
    """

    params = (Param("target", "place", doc="object id or table part; none: where it is"), ATTEMPT)

    def execute(self, env) -> ActionResult:
        if env.held_object is None:
            raise PlanningError("lower needs an object in the hand; approach and close the gripper first")
        target = self.arguments.get("target")
        attempt = int(argument(self, "attempt"))
        held = env.held_object
        held_body = env.model.body(env.names.objects[held]).id
        table = env.table()
        snap = env.snapshot()
        try:
            rise = placement.clear_start(env, env.collision_world())  # off what the start touches, if anything
            world = env.collision_world()
            support_body, support_top, places = _places(env, target, held, table)
            places = rotated(places, attempt)
            to_above, down = _plan(env, world, target, places, support_body, support_top, attempt)
        except PlanningError:
            env.restore(snap)
            raise
        result = _put_down(env, world, to_above, down, support_body, held_body, held, target)
        result.info["unintended_contacts"] = sorted(set(result.info["unintended_contacts"])
                                                    | (rise.unintended_contacts if rise else set()))
        return result

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The raised object is set down upright and let go, the hand over it: on the object the hand hovers
        over, on the table spot it was carried to (or the part's first free place), else back where it stood."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or not hand.raised:
            return ActionResult(False, failure_reason="lowering needs a lifted object")
        target = self.arguments.get("target")
        spot = held.extra.get(CARRIED_TO)
        if isinstance(target, str) and spot is None:
            spot = free_spot(scene, held, target)
            if spot is None:
                return ActionResult(False, failure_reason=placement.no_room(target, held.id))
        elif target is not None and not isinstance(target, str) and hand.over != int(target) and \
                not over(held, scene.object(int(target))):
            return ActionResult(False, failure_reason=f"move over object {target} before lowering onto it")
        _set_down(scene, held, hand, spot)
        # Lowering puts the object down and lets go; the hand retreats straight up, over it.
        held.extra["raised"] = False
        set_flag(scene, "in_hand", None)
        set_flag(scene, "gripper_over", held)
        return ActionResult(True)


def _set_down(scene: SceneGraph, held, hand: ArmState, spot: list[float] | None) -> None:
    """The symbolic put-down: ``held`` on the object under the hand, at the table ``spot``, or straight down."""
    held.extra.pop("tilt_deg", None)  # set down upright, however it leaned before
    held.extra.pop(CARRIED_TO, None)
    if hand.over is not None and hand.over != held.id:
        base = scene.object(hand.over)
        held.position = base.position + [0.0, 0.0, height(base)]
        held.extra["touching"] = [base.id]
    elif spot is not None:
        held.position = held.position.copy()
        held.position[:2] = spot[:2]
        held.position[2] = spot[2]
        held.extra["touching"] = [TOUCHING_TABLE]
    else:
        held.position = held.position - [0.0, 0.0, RAISE_HEIGHT]
        held.extra.pop("touching", None)  # back where it stood, on what it stood on


def _places(env, target, held, table):
    """(support body, the height the held object's bottom rests at there as a function of the hand's turn about the
    vertical, the places for the held object's centre to try in turn) for ``target``."""
    here = env.object_pose(held).pos[:2]
    if isinstance(target, str):
        lo, hi = part_box(env, target)
        places = placement.free_places(env, lo, hi, held)
        if not places:
            raise PlanningError(placement.no_room(target, held))
        inside = bool(np.all(here >= lo) and np.all(here <= hi))
        if inside and placement.is_free(env, here, held):
            places = [here, *places]
        return table.body, _level(table.top_z), placement.spread(places)
    if target is None:
        parts = parts_at(*here)
        near = placement.free_places(env, here - PUT_BACK_RADIUS, here + PUT_BACK_RADIUS, held, prefer=here)
        near = [p for p in near if parts_at(*p) == parts and np.linalg.norm(p - here) <= PUT_BACK_RADIUS]
        return table.body, _level(table.top_z), [here, *placement.spread(near, limit=6)]
    ctx.body_name(env, target)
    tops: dict[float, float] = {}

    def on_target(yaw: float) -> float:  # per turn: a handle turned over a base's higher side meets it higher up
        if yaw not in tops:
            tops[yaw] = placement.resting_top(env, int(target), held, yaw)
        return tops[yaw]

    return env.model.body(env.names.objects[int(target)]).id, on_target, [env.object_pose(int(target)).pos[:2]]


def _level(top: float):
    """The resting height on a flat support, whatever the turn."""
    return lambda yaw: top


def put_down_tries(places: list, target, attempt: int = 0):
    """(place, turn, release gap) in the order tried: each of ``RELEASE_GAPS`` in turn, at each place and, onto
    an object, with the hand turned by each of ``CARRY_TURNS`` (a retry starts from its ``attempt``-th turn: the
    same object set down the same way would lean or fall the same way again).

    Where a neighbour blocks the last centimetres of the descent (fingers beside a tall object), the object is let
    go a little higher over the same place: a short drop still lands it. Onto an object, the hand may also turn
    about the vertical (the held object with it) where it cannot go down as it is.
    """
    yaws = rotated(list(CARRY_TURNS), attempt) if isinstance(target, (int, np.integer)) else [0.0]
    # The release gap varies slowest: every place and turn at the lowest gap before any is let go from higher up
    # (a drop lands the object less surely than another free place does).
    return ((xy, yaw, gap) for gap, xy, yaw in itertools.product(RELEASE_GAPS, places, yaws))


def _plan(env, world, target, places, support_body, support_top, attempt=0):
    """(planned move over the first place that works, straight descent onto it); ``support_top(yaw)``: the height
    the held object's bottom rests at, the hand turned by ``yaw``."""
    reasons = []
    hand = env.ee_pose().pos
    for xy, yaw, gap in put_down_tries(places, target, attempt):
        place = placement.place_pose(env, xy, support_top(yaw), gap, yaw)
        above = place.pos + [0.0, 0.0, ctx.HOVER]
        if yaw == 0.0 and np.linalg.norm(hand[:2] - place.pos[:2]) < 0.01 and hand[2] > place.pos[2]:
            above = hand.copy()  # already over the place (``move`` went there): straight down from here
        try:
            q_above, down = placement.plan_descent(env, world, place, above, support_body,
                                                   gripper_may_touch=not isinstance(target, (int, np.integer)))
            world.allow_contact([])
            to_above = ctx.long_move_planner(env).plan(env.arm_q(), JointGoal(q_above), world)
            return to_above, down
        except PlanningError as e:
            logger.debug("no put-down at %s (turn %.0f deg, gap %.3f): %s", np.round(xy, 3).tolist(),
                         np.degrees(yaw), gap, e)
            reasons.append(str(e))
    raise PlanningError(f"cannot put object {env.held_object} down on {target!r} ({len(places)} places "
                        f"tried): {reasons[0] if reasons else ''}")


def _put_down(env, world, to_above, down, support_body, held_body, held, target) -> ActionResult:
    """Over the place, down, let go, back up; succeeds when the object is released, comes to rest on its target
    and nothing else was moved."""
    world.allow_contact([])
    first = ctx.execute(env, to_above, world)
    world = env.collision_world()
    world.allow_contact([support_body])
    second = ctx.execute(env, down.__class__(np.vstack([env.arm_q(), down.q[1:]]), down.t, down.joint_names),
                         world, allowed={support_body})
    others = {i: env.object_pose(i).pos.copy() for i in env.object_ids if i != held}
    tilt_at_release = tilt_deg(env.object_pose(held).quat)
    between = _between_pads(env, held_body)
    width = ctx.pad_gap(env)
    env.set_gripper(release_command(env))
    env.hold(tol.RELEASE_SETTLE)
    _off_neighbours(env, held_body, width)
    third = _retreat(env, held_body, between)
    env.hold(tol.SETTLE)
    speed = wait_for_rest(env, held_body, waited=tol.SETTLE)
    contacts = first.unintended_contacts | second.unintended_contacts | third.unintended_contacts
    report = ctx.MotionReport(first.duration + second.duration + third.duration, third.final_error, contacts)
    result = checked_result(report, resting_speed=speed, released=env.held_object is None)
    if env.held_object is not None:
        problem = f"object {held} is still in the hand"
    elif not at_rest(speed):
        problem = f"object {held} did not come to rest (speed {speed:.3f} m/s)"
    else:
        problem = misplaced(env, held, held_body, target, support_body, others, tilt_at_release)
    result.success = problem is None
    if problem:
        result.failure_reason = problem
    return result


# m any other object may move while one is put down (a support settling under the added weight) before the
# put-down counts as having disturbed the scene (a stack tipped over, a neighbour dragged along).
DISTURBED = 0.02


def misplaced(env, held: int, held_body: int, target, support_body: int, others: dict,
              tilt_at_release: float | None = None) -> str | None:
    """Why the put-down of ``held`` did not end as asked, from the physics after it came to rest, or ``None``:
    it must touch its target (an object, or the table for a table part) and lean at most ``LEAN_DEG``
    (``muble.stage.rest``) further than
    when it was let go (``tilt_at_release``, degrees), and no other object may have moved more than
    ``DISTURBED``. Put back without a target, it need not touch anything in particular, but it must not lean or
    fall over either."""
    moved = {i: float(np.linalg.norm(env.object_pose(i).pos - p)) for i, p in others.items()}
    moved = {i: d for i, d in moved.items() if d > DISTURBED}
    if moved:
        worst = max(moved, key=moved.get)
        return (f"putting object {held} down moved object {worst} by {100 * moved[worst]:.0f} cm"
                + (f" (and {len(moved) - 1} more)" if len(moved) > 1 else ""))
    if target is not None and support_body not in ctx.touching_bodies(env, {held_body}):
        where = f"object {target}" if isinstance(target, (int, np.integer)) else "the table"
        return f"object {held} did not stay on {where} after it was let go"
    if _hanging(env, held_body):  # let go (no weld), yet held up by the fingers alone
        return f"object {held} hangs in the open fingers after it was let go, resting on nothing"
    if tilt_at_release is not None:  # set down anywhere, it must still stand as it was let go
        quat = env.object_pose(held).quat
        if leaned_over(quat, tilt_at_release) is not None:
            return f"object {held} came to rest leaning {tilt_deg(quat):.0f} degrees (let go at {tilt_at_release:.0f})"
    return None


# m between each pad and the released object that fingers opened against a neighbour close back to: opened
# fully inside a bowl round a released glass, they press on the bowl's wall and would lift it as they rise.
RELEASE_CLEARANCE = 0.005


def gap_command(env, gap: float) -> float:
    """The gripper command that brings the pads ``gap`` apart (between the measured open and closed gaps)."""
    grip = ctx.grip_geometry(env)
    span = grip.open_gap - grip.closed_gap
    closed_share = 0.0 if span <= 1e-6 else (grip.open_gap - gap) / span
    return float(np.clip(2.0 * closed_share - 1.0, -1.0, 1.0))


def _off_neighbours(env, held_body: int, width: float) -> None:
    """Where the opened fingers touch anything but the released object, close them back to ``width`` (the pads'
    gap holding it) plus ``RELEASE_CLEARANCE`` a side."""
    fingers = _finger_bodies(env)
    touched = ctx.touching_bodies(env, fingers) - {held_body} - set(env.collision_world().robot_bodies)
    if touched and ctx.pad_gap(env) > width + 2 * RELEASE_CLEARANCE:
        logger.info("the opened fingers touch %s: closing back to the released object's width", sorted(touched))
        env.set_gripper(gap_command(env, width + 2 * RELEASE_CLEARANCE))
        env.hold(tol.SETTLE)


def _hanging(env, body: int) -> bool:
    """Whether ``body``, let go (no weld), touches the robot and nothing else: held up by the fingers alone."""
    touching = ctx.touching_bodies(env, {body})
    return bool(touching) and not touching - set(env.collision_world().robot_bodies)


def _finger_bodies(env) -> set[int]:
    """The hand's bodies: the hand and everything mounted below it (fingers, pads, tips)."""
    m = env.model
    hand = m.body(env.names.hand_body).id
    return {b for b in range(m.nbody) if below(m, b, hand)}


def _between_pads(env, body: int) -> np.ndarray:
    """The point of ``body`` (its own frame) that is between the pads now."""
    d = env.data
    return d.xmat[body].reshape(3, 3).T @ (env.ee_pose().pos - d.xpos[body])


RETREAT = 0.08  # m the empty hand rises straight up after letting go, before the object is checked for rest
# m the released object may drift at the pads' height (a can set into a bowl slides down its curved floor) before
# the hand follows it sideways: rising with a finger pressed against it would tip it over.
FOLLOW_DRIFT = 0.002
FOLLOW_TRIES = 4  # sideways steps after the released object at most, before the hand rises regardless


def _retreat(env, held_body: int, between: np.ndarray) -> ctx.MotionReport:
    """Rise ``RETREAT`` straight up from the released object, first following it sideways where it drifted from
    between the pads (``between``: that point in the object's frame) or still leans on a finger, up to
    ``FOLLOW_TRIES`` times with a short settle after each (a can in a bowl that slid with the opening finger keeps
    leaning on it after one step, and a finger rising against it tips it over); where a straight line is blocked
    the hand stays (an empty report): the object is down, and the next move starts by rising clear of it."""
    world = env.collision_world()
    # The opened fingers may now brush a neighbour: rising straight up can only leave it, so the plan may
    # start there; contacts in physics with anything but the released object still count.
    world.allow_contact([held_body])
    m, d = env.model, env.data
    near = {m.body(name).id for pair in world.contacts(env.arm_q()) for name in pair} - world.robot_bodies
    world.allow_contact({held_body} | near)
    pose = env.ee_pose()
    fingers = _finger_bodies(env)
    report = ctx.MotionReport()
    for _ in range(FOLLOW_TRIES):
        drift = (d.xpos[held_body] + d.xmat[held_body].reshape(3, 3) @ between - env.ee_pose().pos) * [1.0, 1.0, 0.0]
        if np.linalg.norm(drift) <= FOLLOW_DRIFT and not ctx.touching_bodies(env, {held_body}) & fingers:
            break
        report = placement.merge(report, _straight(env, world, drift, pose.quat, held_body))
        env.hold(tol.STEP_SETTLE)
    for _ in range(UNHOOK_TRIES):
        start_z = float(d.xpos[held_body][2])
        rise = _straight(env, world, np.array([0.0, 0.0, RETREAT]), pose.quat, held_body,
                         stop=lambda e, start_z=start_z: e.data.xpos[held_body][2] - start_z > CAUGHT_RISE)
        report = placement.merge(report, rise)
        if not rise.stopped:
            break
        report = placement.merge(report, _unhook(env, world, held_body, pose.quat, start_z))
    return report


# m the released object may rise with the empty hand before it counts as caught on a finger (a bowl's rim
# wedged on a fingertip, lifted off what it was set on), and the tries to free it before the hand rises regardless.
CAUGHT_RISE = 0.004
UNHOOK_TRIES = 2
UNHOOK_STEP = 0.01  # m the hand moves sideways, off the wall it is caught on, once the object rests again


def _unhook(env, world, held_body: int, quat, start_z: float) -> ctx.MotionReport:
    """Free a finger caught on the released object: back down until the object rests where it was let go, the
    fingers opened fully, then sideways by ``UNHOOK_STEP`` along the push of its contacts on the hand (off the
    wall the finger is pressed against)."""
    d = env.data
    logger.info("the released object rises with the hand, caught on a finger: setting it back and freeing it")
    back = _straight(env, world, np.array([0.0, 0.0, start_z - float(d.xpos[held_body][2]) - 0.001]), quat,
                     held_body)
    env.set_gripper(-1.0)
    env.hold(tol.SETTLE)
    push = _push_on_hand(env, held_body) * [1.0, 1.0, 0.0]
    if np.linalg.norm(push) < 1e-9:
        return back
    step = UNHOOK_STEP * push / np.linalg.norm(push)
    return placement.merge(back, _straight(env, world, step, quat, held_body))


def _push_on_hand(env, body: int) -> np.ndarray:
    """The sum of the contact normals, weighted by penetration, with which ``body`` pushes on the hand."""
    m, d = env.model, env.data
    fingers = _finger_bodies(env)
    total = np.zeros(3)
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        if {b1, b2} & {body} and {b1, b2} & fingers:
            normal = c.frame[:3] if b1 == body else -c.frame[:3]  # MuJoCo's normal points from geom 1 to geom 2
            total += max(-c.dist, 0.0) * normal
    return total


def _straight(env, world, step, quat, held_body, stop=None) -> ctx.MotionReport:
    goal = PoseGoal(Pose(env.ee_pose().pos + step, quat), *tol.FREE)
    try:
        path = ctx.straight_line_planner(env).plan(env.arm_q(), goal, world)
    except PlanningError as e:
        logger.info("no straight move by %s after letting go (%s); the hand stays", np.round(step, 3), e)
        return ctx.MotionReport()
    return ctx.execute(env, path, world, allowed={held_body}, stop=stop)


# s a put-down object may take to come to rest after the hand let go: something set down on a round or tilted
# base may rock a moment before it settles; checked every ``tol.REST_CHECK`` s.
REST_WAIT = 1.5


def wait_for_rest(env, body: int, waited: float) -> float:
    """Hold on in ``tol.REST_CHECK`` s steps while ``body`` is not at rest (``muble.stage.rest.at_rest``), until
    ``REST_WAIT`` has passed since the release (``waited`` of it already has); its last speed (m/s)."""
    speed = float(np.linalg.norm(env.data.cvel[body][3:]))
    while not at_rest(speed) and waited < REST_WAIT:
        env.hold(tol.REST_CHECK)
        waited += tol.REST_CHECK
        speed = float(np.linalg.norm(env.data.cvel[body][3:]))
    return speed

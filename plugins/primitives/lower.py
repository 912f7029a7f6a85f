"""The ``lower`` primitive: put the held object down on an object, on a table part or where it is, let it go and
leave it resting."""
from __future__ import annotations

import itertools
import logging

import numpy as np

from muble import ActionResult, JointGoal, Param, PlanningError, Pose, PoseGoal, PrimitiveAction
from muble.core.table import parts_at
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import placement
from muble_plugins.primitives.common import ATTEMPT, CARRY_TURNS, PART_OPEN, RELEASE_GAPS, checked_result, rotated

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
        attempt = int(self.arguments.get("attempt", 0))
        held = env.held_object
        held_body = env.model.body(env.names.objects[held]).id
        table = env.table()
        snap = env.snapshot()
        try:
            rise = placement.clear_start(env, env.collision_world())  # off what the start touches, if anything
            world = env.collision_world()
            support_body, support_top, places = _places(env, target, held, table)
            places = rotated(places, attempt)
            to_above, down = _plan(env, world, target, places, support_body, support_top)
        except PlanningError:
            env.restore(snap)
            raise
        result = _put_down(env, world, to_above, down, support_body, held_body, held)
        result.info["unintended_contacts"] = sorted(set(result.info["unintended_contacts"])
                                                    | (rise.unintended_contacts if rise else set()))
        return result


def _places(env, target, held, table):
    """(support body, its top, the places for the held object's centre to try in turn) for ``target``."""
    here = env.object_pose(held).pos[:2]
    if isinstance(target, str):
        lo, hi = table.part_region(target)
        places = placement.free_places(env, lo, hi, held)
        if not places:
            raise PlanningError(f"no free space on the {target} part of the table for object {held}; "
                                "choose another part")
        inside = bool(np.all(here >= lo) and np.all(here <= hi))
        if inside and placement.is_free(env, here, held):
            places = [here, *places]
        return table.body, table.top_z, placement.spread(places)
    if target is None:
        parts = parts_at(*here)
        near = placement.free_places(env, here - PUT_BACK_RADIUS, here + PUT_BACK_RADIUS, held, prefer=here)
        near = [p for p in near if parts_at(*p) == parts and np.linalg.norm(p - here) <= PUT_BACK_RADIUS]
        return table.body, table.top_z, [here, *placement.spread(near, limit=6)]
    ctx.body_name(env, target)
    return (env.model.body(env.names.objects[int(target)]).id, placement.resting_top(env, int(target), held),
            [env.object_pose(int(target)).pos[:2]])


def put_down_tries(places: list, target):
    """(place, turn, release gap) in the order tried: each place in turn, at each of ``RELEASE_GAPS`` and, onto
    an object, with the hand turned by each of ``CARRY_TURNS``.

    Where a neighbour blocks the last centimetres of the descent (fingers beside a tall object), the object is let
    go a little higher over the same place: a short drop still lands it. Onto an object, the hand may also turn
    about the vertical (the held object with it) where it cannot go down as it is.
    """
    yaws = CARRY_TURNS if isinstance(target, (int, np.integer)) else (0.0,)
    return itertools.product(places, yaws, RELEASE_GAPS)


def _plan(env, world, target, places, support_body, support_top):
    """(planned move over the first place that works, straight descent onto it)."""
    reasons = []
    hand = env.ee_pose().pos
    for xy, yaw, gap in put_down_tries(places, target):
        place = placement.place_pose(env, xy, support_top, gap, yaw)
        above = place.pos + [0.0, 0.0, ctx.HOVER]
        if yaw == 0.0 and np.linalg.norm(hand[:2] - place.pos[:2]) < 0.01 and hand[2] > place.pos[2]:
            above = hand.copy()  # already over the place (``move`` went there): straight down from here
        try:
            q_above, down = placement.plan_descent(env, world, place, above, support_body)
            world.allow_contact([])
            to_above = ctx.planner(env, "ompl").plan(env.arm_q(), JointGoal(q_above), world)
            return to_above, down
        except PlanningError as e:
            logger.debug("no put-down at %s (turn %.0f deg, gap %.3f): %s", np.round(xy, 3).tolist(),
                         np.degrees(yaw), gap, e)
            reasons.append(str(e))
    raise PlanningError(f"cannot put object {env.held_object} down on {target!r} ({len(places)} places "
                        f"tried): {reasons[0] if reasons else ''}")


def _put_down(env, world, to_above, down, support_body, held_body, held) -> ActionResult:
    """Over the place, down, let go, back up; succeeds when the object is released and comes to rest."""
    world.allow_contact([])
    first = ctx.execute(env, to_above, world)
    world = env.collision_world()
    world.allow_contact([support_body])
    second = ctx.execute(env, down.__class__(np.vstack([env.arm_q(), down.q[1:]]), down.t, down.joint_names),
                         world, allowed={support_body})
    env.set_gripper(release_command(env))
    env.hold(0.5)
    third = _retreat(env, held_body)
    env.hold(0.3)
    speed = wait_for_rest(env, held_body, waited=0.3)
    contacts = first.unintended_contacts | second.unintended_contacts | third.unintended_contacts
    report = ctx.MotionReport(first.duration + second.duration + third.duration, third.final_error, contacts)
    result = checked_result(report, resting_speed=speed, released=env.held_object is None)
    result.success = env.held_object is None and speed < RESTING_SPEED
    if not result.success:
        result.failure_reason = f"object {held} did not come to rest (speed {speed:.3f} m/s)"
    return result


# m between the pads holding an object below which the hold counts as a thin part (a rim, a handle, a stem) and
# it is let go with the hand part open.
THIN_HOLD = 0.025


def release_command(env) -> float:
    """The gripper command that lets the held object go: fully open (-1), or for a thin part held (a rim, a
    handle, a stem; under ``THIN_HOLD``) only part way: opened fully, the finger inside a rim would reach across
    to the far side and catch it on the way up."""
    return PART_OPEN if ctx.pad_gap(env) < THIN_HOLD else -1.0


RETREAT = 0.08  # m the empty hand rises straight up after letting go, before the object is checked for rest


def _retreat(env, held_body: int) -> ctx.MotionReport:
    """Rise ``RETREAT`` straight up from the released object; where the straight line is blocked the hand stays
    (an empty report): the object is down, and the next move starts by rising clear of it."""
    world = env.collision_world()
    # The opened fingers may now brush a neighbour: rising straight up can only leave it, so the plan may
    # start there; contacts in physics with anything but the released object still count.
    world.allow_contact([held_body])
    m = env.model
    near = {m.body(name).id for pair in world.contacts(env.arm_q()) for name in pair} - world.robot_bodies
    world.allow_contact({held_body} | near)
    pose = env.ee_pose()
    try:
        retreat = ctx.planner(env, "straight_line").plan(
            env.arm_q(), PoseGoal(Pose(pose.pos + [0.0, 0.0, RETREAT], pose.quat), 0.005, 0.05), world)
        return ctx.execute(env, retreat, world, allowed={held_body})
    except PlanningError as e:
        logger.info("no straight retreat after letting go (%s); the hand stays where it released", e)
        return ctx.MotionReport()


RESTING_SPEED = 0.01  # m/s (the body's linear speed) below which a put-down object counts as resting
# s a put-down object may take to come to rest after the hand let go: something set down on a round or tilted
# base may rock a moment before it settles; checked every 0.25 s.
REST_WAIT = 1.5


def wait_for_rest(env, body: int, waited: float) -> float:
    """Hold on in 0.25 s steps while ``body`` moves at ``RESTING_SPEED`` or more, until ``REST_WAIT`` has passed
    since the release (``waited`` of it already has); its last speed (m/s)."""
    speed = float(np.linalg.norm(env.data.cvel[body][3:]))
    while speed >= RESTING_SPEED and waited < REST_WAIT:
        env.hold(0.25)
        waited += 0.25
        speed = float(np.linalg.norm(env.data.cvel[body][3:]))
    return speed

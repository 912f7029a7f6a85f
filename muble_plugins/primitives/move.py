"""The ``move`` primitive: the hand above an object or a table part, by a planned collision-free move."""
from __future__ import annotations

import itertools
import logging

import numpy as np

from muble import ActionResult, JointGoal, PlanningError, PoseGoal, PrimitiveAction, SceneGraph
from muble.core.params import argument
from muble.core.symbolic import CARRIED_TO, ArmState, set_flag
from muble.stage.footprint import free_spot
from muble.stage.table import part_box
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import placement
from muble_plugins.primitives.common import ATTEMPT, CARRY_TURNS, RELEASE_GAPS, TARGET_PLACE, checked_result, rotated

logger = logging.getLogger(__name__)


class Move(PrimitiveAction):
    """Move the hand above an object (scene id) or a table part (left/right/front/back/centre).

    Carrying an object to a table part, the hand goes over the free place ``lower`` will use: the first place
    (nearest the part's centre) that the arm reaches and can descend to straight without touching anything.
    """

    params = (TARGET_PLACE, ATTEMPT)
    hand_at_target = "over"

    def execute(self, env) -> ActionResult:
        target = self.arguments.get("target")
        attempt = int(argument(self, "attempt"))
        held = env.held_object
        if isinstance(target, str):
            part_box(env, target)  # an unknown part name fails before anything moves
        else:
            ctx.body_name(env, target)
        snap = env.snapshot()
        try:
            rise = placement.clear_start(env, env.collision_world())  # off what the start touches, if anything
            world = env.collision_world()
            if isinstance(target, str) and env.held_object is not None:
                goals = [JointGoal(over_free_place(env, world, target, attempt))]
            else:
                goals = rotated(hover_goals(env, target), attempt)
            trajectory = first_planned(env, world, goals)
        except PlanningError:
            env.restore(snap)
            raise
        report = ctx.execute(env, trajectory, world)
        return checked_result(placement.merge(rise, report), env, held, target=target)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The hand hovers over the object, or over the table part; a raised object in it travels along, to the
        part's first free place (``free_spot``), where ``lower`` will put it."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is not None and not hand.raised:
            return ActionResult(False, failure_reason="lift the held object before moving")
        set_flag(scene, "approached", None)
        if isinstance(self.arguments.get("target"), str):  # a table part
            set_flag(scene, "gripper_over", None)
            spot = free_spot(scene, held, self.arguments["target"]) if held is not None else None
            if held is not None and spot is None:
                return ActionResult(False, failure_reason=placement.no_room(self.arguments["target"], held.id))
            if held is not None:
                held.extra[CARRIED_TO] = spot
            xy = spot[:2] if spot else None
        else:
            target = scene.object(int(self.arguments["target"]))
            set_flag(scene, "gripper_over", target)
            if held is not None:
                held.extra.pop(CARRIED_TO, None)
            xy = target.position[:2]
        if held is not None and xy is not None:
            # The lifted object travels with the gripper.
            held.position = held.position.copy()
            held.position[:2] = xy
        return ActionResult(True)


def first_planned(env, world, goals: list):
    """The planned move to the first of ``goals`` that can be reached; the first goal's error when none can."""
    reasons = []
    for goal in goals:
        world.allow_contact([])
        try:
            return ctx.long_move_planner(env).plan(env.arm_q(), goal, world)
        except PlanningError as e:
            reasons.append(e)
    raise reasons[0]


# rad the empty hand may turn about the vertical to hover over an object, tried in this order: as it is, then a
# quarter turn either way (the open fingers turned away from a tall neighbour), then the eighths between.
HOVER_TURNS = tuple(np.radians([0, 90, -90, 45, -45]))
# m above everything standing near the target that the hand hovers at, tried last, where the usual height
# (``ctx.HOVER``) is out of the arm's reach: over an object at the far edge of the workspace the arm reaches down to
# grasp it (the generator's reach check asks exactly that) but not 12 cm above it (measured: 5-6 mm short).
LOW_HOVERS = (0.06, 0.03)


def hover_goals(env, target) -> list[PoseGoal]:
    """The hover poses over ``target`` to try in turn, the usual pose first, each once: the hand turned by each of
    ``HOVER_TURNS`` (``CARRY_TURNS`` when it carries an object), first at the usual height, then above everything
    standing near the target, then lower (``LOW_HOVERS``).

    Over an object near the edge of the workspace the hand may have to turn about the vertical (a carried object
    turning with it) to reach, and beside a tall neighbour rise above it or turn the open fingers away from it.
    """
    turns = CARRY_TURNS if env.held_object is not None else HOVER_TURNS
    goals = []
    tries = [(clear, yaw, ctx.HOVER) for clear, yaw in itertools.product((False, True), turns)]
    tries += [(True, yaw, height) for height, yaw in itertools.product(LOW_HOVERS, turns)]
    for clear, yaw, height in tries:
        goal = hover_goal(env, target, yaw, clear, height)
        if not any(np.allclose(goal.pose.pos, g.pose.pos) and np.allclose(goal.pose.quat, g.pose.quat)
                   for g in goals):
            goals.append(goal)
    return goals


def hover_goal(env, target, yaw: float = 0.0, clear: bool = False, height: float = ctx.HOVER) -> PoseGoal:
    """Hover pose over ``target``, ``height`` above it: the hand turned by ``yaw`` about the vertical; with
    ``clear``, above everything standing near it rather than above the target alone."""
    table = env.table()
    if isinstance(target, str):
        lo, hi = part_box(env, target)
        xy, top = 0.5 * (lo + hi), table.top_z
    else:
        xy, top = env.object_pose(int(target)).pos[:2], env.object_top(int(target))
    quat = env.top_down(yaw)
    if env.held_object is not None:
        # Carrying: the hand keeps its orientation (the object stays as it was lifted, whatever the grasp)
        # and the object's centre, not the hand, comes over the target, ready to be lowered onto it. Turned
        # by ``yaw`` about the vertical, the object's offset from the hand turns too.
        offset, quat = placement.turned(env, yaw)
        xy = xy - offset
    if isinstance(target, str) or clear:
        top = max(top, placement.clear_top(env, xy, table.top_z, env.held_object))
    return ctx.hover_pose(env, xy, top + placement.held_depth(env), quat, height)


def over_free_place(env, world, part: str, attempt: int = 0) -> np.ndarray:
    """The arm configuration ``ctx.HOVER`` over the first free place on ``part`` (rotated by ``attempt``) that the
    held object can be lowered to straight, released at the first of ``RELEASE_GAPS``.

    Every place is tried with the hand as it carries the object first; only where none can be descended to does
    the hand turn about the vertical (each of ``CARRY_TURNS``, the object turning with it): beside a tall
    neighbour the forearm, not the object, may be what blocks the way down, and a turned wrist bends the arm the
    other way. ``lower`` then finds the hand over the place and goes straight down as it is turned.
    """
    table = env.table()
    lo, hi = part_box(env, part)
    reasons, any_free = [], False
    for yaw in CARRY_TURNS:  # the places for a turn are found only when the turns before it gave none
        places = placement.free_places(env, lo, hi, env.held_object, yaw=yaw)
        any_free = any_free or bool(places)
        for xy in rotated(placement.spread(places), attempt):
            place = placement.place_pose(env, xy, table.top_z, RELEASE_GAPS[0], yaw)
            top = placement.clear_top(env, xy, table.top_z, env.held_object)
            above = np.array([place.pos[0], place.pos[1], top + placement.held_depth(env) + ctx.HOVER])
            try:
                q_above, _ = placement.plan_descent(env, world, place, above, table.body)
                return q_above
            except PlanningError as e:
                logger.debug("no descent to %s (turn %.0f deg): %s", np.round(xy, 3).tolist(), np.degrees(yaw), e)
                reasons.append(f"{np.round(xy, 3).tolist()}: {e}")
    if not any_free:
        raise PlanningError(placement.no_room(part, env.held_object))
    raise PlanningError(f"no free place on the {part} part of the table can be reached and descended to "
                        f"({len(reasons)} places and turns tried): {reasons[0]}")

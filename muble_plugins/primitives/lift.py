"""The ``lift`` primitive: the hand (and what it holds) straight up, or around what overhangs it."""
from __future__ import annotations

import logging

import numpy as np

from muble import ActionResult, JointGoal, Param, PlanningError, Pose, PoseGoal, PrimitiveAction, SceneGraph
from muble.core.params import argument
from muble.core.symbolic import RAISE_HEIGHT, ArmState
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import tolerances as tol
from muble_plugins.primitives.common import checked_result

logger = logging.getLogger(__name__)

LIFT_HEIGHT = 0.15  # m risen when no height is given


class Lift(PrimitiveAction):
    """Raise the hand (and what it holds) straight up by ``height`` metres (default 0.15)."""

    params = (Param("height", "number", low=0.01, high=0.4, default=LIFT_HEIGHT, doc="metres"),)

    def execute(self, env) -> ActionResult:
        height = float(argument(self, "height"))
        held = env.held_object
        world = env.collision_world()
        support = _leaving(env, world)
        pose = env.ee_pose()
        goal = PoseGoal(Pose(pose.pos + [0.0, 0.0, height], pose.quat), *tol.FREE)
        try:
            trajectory = ctx.straight_line_planner(env).plan(env.arm_q(), goal, world)
        except PlanningError as e:
            logger.info("straight lift failed (%s); rising %.0f cm and planning the rest", e, FIRST_RISE * 100)
            report = lift_around(env, world, support, pose, goal, height)
        else:
            report = ctx.execute(env, trajectory, world, allowed=support)
        return _checked(env, report, held, height)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The grasped object rises off its support, ``RAISE_HEIGHT`` up whatever the ``height``."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or hand.raised:
            return ActionResult(False, failure_reason="lifting needs a grasped object resting on its support")
        held.extra["raised"] = True
        held.extra["touching"] = []
        held.position = held.position + [0.0, 0.0, RAISE_HEIGHT]
        return ActionResult(True)


def _leaving(env, world) -> set[int]:
    """The bodies the hand and the held object may touch while rising, now allowed in ``world``: what they rest on
    or touch in physics, and what they already overlap within the planning clearance (a neighbour leaning on the
    object, a tray rim under a wine glass's foot): rising can only move away from it."""
    own = set(world.robot_bodies)
    if env.held_object is not None:
        own.add(env.model.body(env.names.objects[env.held_object]).id)
    support = ctx.touching_bodies(env, own)
    world.allow_contact(support)
    m = env.model
    for pair in world.contacts(env.arm_q()):
        support |= {m.body(name).id for name in pair if m.body(name).id not in own}
    world.allow_contact(support)
    return support


FIRST_RISE = 0.03  # m of straight rise (at most the height asked) that clears the support before planning freely


def lift_around(env, world, support: set[int], pose: Pose, goal: PoseGoal, height: float) -> ctx.MotionReport:
    """The lift where the straight line up breaks off (near a joint limit or a singularity): a short straight
    rise of ``FIRST_RISE`` off the support, then a planned move to the raised pose; where even the short rise is
    blocked (something overhangs the object: a tray's flared rim over a glass's foot), a planned move the whole
    way, sideways first where needed, touching only the support."""
    rise = PoseGoal(Pose(pose.pos + [0.0, 0.0, min(height, FIRST_RISE)], pose.quat), *tol.FREE)
    try:
        first = ctx.straight_line_planner(env).plan(env.arm_q(), rise, world)
    except PlanningError:
        q_goal = _raised(env, world, goal)
        trajectory = ctx.long_move_planner(env).plan(env.arm_q(), JointGoal(q_goal), world)
        return ctx.execute(env, trajectory, world, allowed=support)
    report = ctx.execute(env, first, world, allowed=support)
    world = env.collision_world()
    q_goal = _raised(env, world, goal)
    trajectory = ctx.long_move_planner(env).plan(env.arm_q(), JointGoal(q_goal), world)
    second = ctx.execute(env, trajectory, world)
    return ctx.MotionReport(report.duration + second.duration, second.final_error,
                            report.unintended_contacts | second.unintended_contacts)


def _checked(env, report: ctx.MotionReport, held: int | None, height: float) -> ActionResult:
    """Lifting an object succeeds only when it ends held and clear of every support."""
    result = checked_result(report, env, held, height=height)
    if result.success and held is not None and not env.is_lifted(held):
        result.success = False
        result.failure_reason = f"object {held} is still supported after lifting (caught on something)"
    return result


# (dx, dy) in m by which the raised pose may shift where something overhangs it, tried in this order: none, then 8
# directions 4 cm away, then 8 cm away (the nearest pose beside the overhang first).
LIFT_SIDESTEPS = ((0.0, 0.0), *((r * np.cos(a), r * np.sin(a)) for r in (0.04, 0.08)
                                for a in np.linspace(0.0, 2 * np.pi, 8, endpoint=False)))


def _raised(env, world, goal: PoseGoal) -> np.ndarray:
    """An arm configuration for the raised pose, or, where something overhangs it (a bowl stacked on a
    neighbour, its rim over the object), for the nearest pose beside it at the same height (``LIFT_SIDESTEPS``)."""
    reasons = []
    for dx, dy in LIFT_SIDESTEPS:
        shifted = PoseGoal(Pose(goal.pose.pos + [dx, dy, 0.0], goal.pose.quat), goal.position_tolerance,
                           goal.orientation_tolerance)
        try:
            return world.inverse_kinematics(shifted, seeds=env.arm_q()[None])
        except PlanningError as e:
            reasons.append(e)
    raise reasons[0]

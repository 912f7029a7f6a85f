"""Arm motion primitives: move above a target, approach for grasping, lift, lower (put down), move_vel.

Each plans completely before it moves where it can, so a ``PlanningError`` leaves the environment as it was; a
primitive that fails after moving restores the snapshot taken at its start before re-raising.
"""
from __future__ import annotations

import itertools
import logging

import numpy as np

from muble import ActionResult, JointGoal, Param, PlanningError, Pose, PoseGoal, PrimitiveAction
from muble.core.table import parts_at
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import placement
from muble_plugins.primitives.grasping import PAD_MARGIN, PRE_GRASP, grasp_approach, grasp_candidates, hand_clearance

logger = logging.getLogger(__name__)

# Clearance (m) the open hand keeps from the target in the grasp pose and on the way in: the fingers must
# not already press on it, or closing would not pinch it between the pads.
TARGET_TOUCH = 0.001
GRIP_BACKOFF = 0.03  # m a grasp may be moved back along its approach to clear the target
PRE_GRASP_HIGH = 0.18  # m above a top-down grasp for the second pre-grasp tried
PRE_GRASP_TRACKING = 0.05  # rad any arm joint may lag the pre-grasp configuration before the descent
PRESHAPE_COMMANDS = (0.0,)  # gripper commands (-1 open, 1 closed) tried after the fully open hand
PRESHAPE_SETTLE = 0.5  # s for the fingers to reach a part-way opening
PRESHAPE_SLACK = 0.002  # m the part-way opening may still close while the arm moves
PAD_OVERLAP = 0.004  # m the pads' middle stays inside the object when a grasp is backed off
PAD_HALF_WIDTH = 0.006  # m: the part of an object between the pads, across the closing direction
RELEASE_GAPS = (0.004, 0.015, 0.03)  # m between the held object's bottom and its support when let go
CARRY_TURNS = tuple(np.radians([0, 45, -45, 90, -90, 135, -135, 180]))  # rad tried turning a carried object
LONG_SWING = 2.0  # rad any arm joint travels to a pre-grasp pose beyond which other grasps are looked for first
SWING_ALTERNATIVES = 6  # candidates tried for a nearer grasp once one with a long swing was found
HOVER_TURNS = tuple(np.radians([0, 90, -90, 45, -45]))  # rad the empty hand may turn to hover over an object
THIN_HOLD = 0.025  # m between the pads holding an object, below which it is let go with the hand part open
RESTING_SPEED = 0.01  # m/s below which a put-down object counts as resting
REST_WAIT = 1.5  # s a put-down object may take to come to rest after the hand let go
LIFT_SIDESTEPS = ((0.0, 0.0), *((r * np.cos(a), r * np.sin(a)) for r in (0.04, 0.08)
                                for a in np.linspace(0.0, 2 * np.pi, 8, endpoint=False)))
PUT_BACK_RADIUS = 0.05  # m a put-down without a target may shift the object to find a free place
FEASIBLE_CANDIDATES = 16  # grasp candidates per hand opening that ``Approach.feasible`` tries at most
FEASIBLE_RISE = 0.10  # m the hand must rise straight up holding the object for ``Approach.feasible``
FEASIBLE_IK_RESTARTS = 12  # random inverse-kinematics restarts per pose in ``Approach.feasible``
FINGERS_STILL = 0.005  # m/s (rad/s) of finger joint speed below which the fingers count as at rest
FINGERS_OPEN_SLACK = 0.003  # m the pads may still lack of the measured open gap for the hand to count as open
END_TRACKING = 0.05  # rad any arm joint may end from the planned final configuration for the motion to count
MOVE_VEL_TOLERANCE = 0.01  # m between the hand's travel and velocity x duration
MAX_ATTEMPT = 16  # ``attempt`` values a retrying agent may pass

# Typed parameters: the action loop rejects other calls as invalid actions before anything runs.
TARGET_PLACE = Param("target", "place", required=True, doc="object id or table part")
ATTEMPT = Param("attempt", "int", low=0, high=MAX_ATTEMPT,
                doc="retry number: start from the attempt-th best option (grasp, place, hover pose)")


def rotated(options: list, attempt: int) -> list:
    """``options`` with the ``attempt``-th first: a retry tries the alternatives before the option that failed."""
    if not options:
        return options
    k = int(attempt) % len(options)
    return list(options[k:]) + list(options[:k])


def _result(report: ctx.MotionReport, env=None, held: int | None = None, **info) -> ActionResult:
    """The motion's result, checked: the arm ended where it was sent, and it still holds what it held."""
    info.update(unintended_contacts=sorted(report.unintended_contacts), duration=report.duration,
                final_error=report.final_error)
    if np.isfinite(report.final_error) and report.final_error > END_TRACKING:
        return ActionResult(False, info=info, failure_reason=f"the arm ended {report.final_error:.3f} rad from the "
                                                            f"planned configuration (blocked or overloaded)")
    if env is not None and held is not None and env.held_object != held:
        return ActionResult(False, info=info, failure_reason=f"object {held} slipped out of the hand while moving")
    return ActionResult(True, info=info)


def _part_places(env, part: str, held: int) -> list[np.ndarray]:
    """Free places for the held object's centre on a table part, nearest the part's centre first."""
    lo, hi = ctx.table(env).part_region(part)
    return placement.free_places(env, lo, hi, held)


class Move(PrimitiveAction):
    """Move the hand above an object (scene id) or a table part (left/right/front/back/centre).

    Carrying an object to a table part, the hand goes over the free place ``lower`` will use: the first place
    (nearest the part's centre) that the arm reaches and can descend to straight without touching anything.
    """

    params = (TARGET_PLACE, ATTEMPT)
    hand_at_target = "over"

    def execute(self, env) -> ActionResult:
        target = self.arguments.get("target")
        attempt = int(self.arguments.get("attempt", 0))
        held = env.held_object
        if isinstance(target, str):
            ctx.table(env).part_region(target)  # an unknown part name fails before anything moves
        else:
            ctx.body_name(env, target)
        snap = env.snapshot()
        try:
            rise = placement.clear_start(env, ctx.collision_world(env))
            world = ctx.collision_world(env)
            if isinstance(target, str) and env.held_object is not None:
                goals = [JointGoal(self._over_free_place(env, world, target, attempt))]
            else:
                # Over an object near the edge of the workspace the hand may have to turn about the vertical
                # (a carried object turning with it) to reach, and beside a tall neighbour rise above it or turn
                # the open fingers away from it; the first that works is taken, the usual pose first.
                turns = CARRY_TURNS if env.held_object is not None else HOVER_TURNS
                goals = []
                for clear, yaw in itertools.product((False, True), turns):
                    goal = self._hover_goal(env, target, yaw, clear)
                    if not any(np.allclose(goal.pose.pos, g.pose.pos) and np.allclose(goal.pose.quat, g.pose.quat)
                               for g in goals):
                        goals.append(goal)
                goals = rotated(goals, attempt)
            reasons = []
            for goal in goals:
                world.allow_contact([])
                try:
                    trajectory = ctx.planner(env, "ompl").plan(env.arm_q(), goal, world)
                    break
                except PlanningError as e:
                    reasons.append(e)
            else:
                raise reasons[0]
        except PlanningError:
            env.restore(snap)
            raise
        report = ctx.execute(env, trajectory, world)
        return _result(placement.merge(rise, report), env, held, target=target)

    @staticmethod
    def _hover_goal(env, target, yaw: float = 0.0, clear: bool = False) -> PoseGoal:
        """Hover pose over ``target``: the hand turned by ``yaw`` about the vertical; with ``clear``, above
        everything standing near it rather than above the target alone."""
        table = ctx.table(env)
        if isinstance(target, str):
            lo, hi = table.part_region(target)
            xy, top = 0.5 * (lo + hi), table.top_z
        else:
            xy, top = env.object_pose(int(target)).pos[:2], ctx.object_top(env, int(target))
        quat = ctx.top_down(env, yaw)
        if env.held_object is not None:
            # Carrying: the hand keeps its orientation (the object stays as it was lifted, whatever the grasp)
            # and the object's centre, not the hand, comes over the target, ready to be lowered onto it. Turned
            # by ``yaw`` about the vertical, the object's offset from the hand turns too.
            offset, quat = placement.turned(env, yaw)
            xy = xy - offset
        if isinstance(target, str) or clear:
            top = max(top, placement.clear_top(env, xy, table.top_z, env.held_object))
        return ctx.hover_pose(env, xy, top + placement.held_depth(env), quat)

    @staticmethod
    def _over_free_place(env, world, part: str, attempt: int = 0) -> np.ndarray:
        table = ctx.table(env)
        places = _part_places(env, part, env.held_object)
        if not places:
            raise PlanningError(f"no free space on the {part} part of the table for object {env.held_object}; "
                                "choose another part")
        reasons = []
        for xy in rotated(placement.spread(places), attempt):
            place = placement.place_pose(env, xy, table.top_z, RELEASE_GAPS[0])
            top = placement.clear_top(env, xy, table.top_z, env.held_object)
            above = np.array([place.pos[0], place.pos[1], top + placement.held_depth(env) + ctx.HOVER])
            try:
                q_above, _ = placement.plan_descent(env, world, place, above, table.body)
                return q_above
            except PlanningError as e:
                logger.debug("no descent to %s: %s", np.round(xy, 3).tolist(), e)
                reasons.append(f"{np.round(xy, 3).tolist()}: {e}")
        raise PlanningError(f"no free place on the {part} part of the table can be reached and descended to "
                            f"({len(reasons)} tried): {reasons[0]}")


class Approach(PrimitiveAction):
    """Bring the open hand into the grasp pose of an object: over it by a planned move, then straight in.

    Candidates come from the object's grasp frames (``grasp_candidates``). One is taken when its grasp pose and
    its straight descent are collision-free, the open fingers included: the target itself may only be touched
    within ``TARGET_TOUCH`` (the pads brushing it), never pierced, so that closing really pinches it.
    """

    params = (Param("target", "object", required=True), ATTEMPT)
    hand_at_target = "grasp"

    def execute(self, env) -> ActionResult:
        obj_id = int(self.arguments["target"])
        attempt = int(self.arguments.get("attempt", 0))
        body = ctx.body_name(env, obj_id)
        if env.held_object is not None:
            raise PlanningError(f"the hand already holds object {env.held_object}; lower it before approaching")
        snap = env.snapshot()
        grip = ctx.grip_geometry(env)
        reasons, tried = [], 0
        for command in (-1.0, *PRESHAPE_COMMANDS):
            try:
                world, candidates = self._candidates(env, obj_id, body, command)
            except PlanningError:
                env.restore(snap)
                raise
            tried += len(candidates)
            candidates = rotated(candidates, attempt)
            # A grasp whose arm configuration lies on another branch (wrist turned most of a turn) is kept back:
            # on such a long swing the wrist lags and the hand sweeps where the plan did not go. A few more
            # candidates are tried for a nearer one first.
            swing, after_swing = None, 0
            for grasp in candidates:
                try:
                    to_pre, down = self._plan(env, world, body, grasp, grip)
                except PlanningError as e:
                    reasons.append(str(e))
                else:
                    if np.max(np.abs(to_pre.q[-1] - to_pre.q[0])) <= LONG_SWING:
                        return self._go(env, snap, obj_id, body, to_pre, down, grasp, len(reasons) + 1)
                    swing = swing or (to_pre, down, grasp)
                if swing is not None:
                    after_swing += 1
                    if after_swing == SWING_ALTERNATIVES:
                        break
            if swing is not None:
                return self._go(env, snap, obj_id, body, *swing, len(reasons) + 1)
        env.restore(snap)
        raise PlanningError(f"no grasp of object {obj_id} is reachable without collision "
                            f"({tried} tried): {reasons[0] if reasons else ''}")

    def feasible(self, env) -> None:
        """Raise ``PlanningError`` unless the target can be grasped and put down again from the current state:
        one of the first ``FEASIBLE_CANDIDATES`` grasps that ``execute`` would try is reached without collision
        (the planned move over it and the straight move in), and holding the object there the hand rises
        straight up off its support (the reverse of setting it back down where it stands). Inverse kinematics
        gets ``FEASIBLE_IK_RESTARTS`` restarts, so the check is a little stricter than ``execute``. Nothing
        moves: the environment is restored."""
        obj_id = int(self.arguments["target"])
        body = ctx.body_name(env, obj_id)
        if env.held_object is not None:
            raise PlanningError(f"the hand already holds object {env.held_object}; lower it before approaching")
        snap = env.snapshot()
        grip = ctx.grip_geometry(env)
        reasons, tried = [], 0
        try:
            for command in (-1.0, *PRESHAPE_COMMANDS):
                if reasons and all("out of reach" in r for r in reasons):
                    break  # a narrower hand reaches no farther
                world, candidates = self._candidates(env, obj_id, body, command,
                                                     settle=not _fingers_open(env, command, grip))
                for grasp in candidates[:FEASIBLE_CANDIDATES]:
                    tried += 1
                    try:
                        _, down = self._plan(env, world, body, grasp, grip, FEASIBLE_IK_RESTARTS)
                        self._rise_holding(env, world, body, down.q[-1])
                        return
                    except PlanningError as e:
                        logger.debug("grasp %d of object %d (hand %+.0f): %s", tried, obj_id, command, e)
                        reasons.append(str(e))
                    finally:
                        world.hold(None)
                        world.allow_contact([])
                        world.sync(env.data)
        finally:
            env.restore(snap)
        raise PlanningError(f"no grasp of object {obj_id} is reachable without collision and rises clear of its "
                            f"support ({tried} tried): {reasons[0] if reasons else ''}")

    @staticmethod
    def _candidates(env, obj_id: int, body: str, command: float, settle: bool = True):
        """The collision world and the ranked grasp candidates with the hand opened by ``command`` (-1: fully;
        a part-way opening, still wide enough for a rim or a handle, may fit in clutter where the open hand
        touches something, or next to the object's own handle). The fingers are moved there in physics
        (``settle=False``: they already are)."""
        model = env.object_models[obj_id]
        grip = ctx.grip_geometry(env)
        table = ctx.table(env)
        if settle:
            env.set_gripper(command)
            env.hold(0.3 if command == -1.0 else PRESHAPE_SETTLE)
        if command == -1.0:
            max_width = grip.max_width  # the fingers go on opening on the way; the measured open gap applies
        else:
            max_width = ctx.pad_gap(env) - 2 * PAD_MARGIN - PRESHAPE_SLACK
        world = ctx.collision_world(env)
        # Ranked by how far the hand stays from the neighbours, with more directions around round objects.
        candidates = grasp_candidates(env.object_pose(obj_id), model, table.top_z, max_width=max_width,
                                      rest_quat=ctx.world_rest_quat(env), grip=grip,
                                      clearance=hand_clearance(world, body, ignore=[table.body]))
        if not candidates and command == -1.0:
            raise PlanningError(f"object {obj_id} ({model.spec.category}) has no grasp that fits this gripper "
                                f"(parts {grip.closed_gap * 1000:.0f}-{grip.max_width * 1000:.0f} mm thick); "
                                "choose another robot.gripper or object")
        return world, candidates

    @staticmethod
    def _rise_holding(env, world, body: str, q_grasp: np.ndarray) -> None:
        """Raise ``PlanningError`` unless, holding ``body`` at ``q_grasp``, the hand rises ``FEASIBLE_RISE``
        straight up touching only what the object stands on or already overlaps (as ``lift`` allows)."""
        m = world.model
        world.kinematics.set_q(q_grasp)
        world.hold(body)
        held = m.body(body).id
        support = {ctx.table(env).body}
        world.allow_contact(support)
        support |= {m.body(name).id for pair in world.contacts(q_grasp) for name in pair} - world.robot_bodies - {held}
        world.allow_contact(support)
        pose = world.ee_pose(q_grasp)
        goal = PoseGoal(Pose(pose.pos + [0.0, 0.0, FEASIBLE_RISE], pose.quat), 0.005, 0.05)
        ctx.planner(env, "straight_line").plan(q_grasp, goal, world)

    @staticmethod
    def _go(env, snap, obj_id: int, body: str, to_pre, down, grasp: Pose, tried: int) -> ActionResult:
        def lag() -> float:  # how far the arm is from the pre-grasp configuration (rad, worst joint)
            return float(np.max(np.abs(env.arm_q() - to_pre.q[-1])))

        world = ctx.collision_world(env)
        first = ctx.execute(env, to_pre, world)
        env.hold(0.3)
        for _ in range(2):
            # A long swing can leave a weak wrist joint far behind its set-point (the other joints' motion
            # drags it); descending from there would meet the object with the hand turned, so move again.
            if lag() <= PRE_GRASP_TRACKING:
                break
            world.allow_contact([])
            first = ctx.execute(env, ctx.planner(env, "ompl").plan(env.arm_q(), JointGoal(to_pre.q[-1]), world),
                                world)
            env.hold(0.3)
        if lag() > PRE_GRASP_TRACKING:
            error = lag()
            env.restore(snap)
            raise PlanningError(f"the arm did not reach the pre-grasp pose over object {obj_id} "
                                f"(joint error {error:.2f} rad)")
        env.tare()  # the empty hand, still: the zero for weighing
        world = ctx.collision_world(env)
        second = ctx.execute(env, down.__class__(
            np.vstack([env.arm_q(), down.q[1:]]), down.t, down.joint_names), world,
            allowed={env.model.body(body).id})
        if second.final_error > PRE_GRASP_TRACKING:
            # Held up on the way in (a finger on a neighbour): closing here would not hold the object.
            contacts = sorted(first.unintended_contacts | second.unintended_contacts)
            env.restore(snap)
            raise PlanningError(f"the hand was stopped on its way in to object {obj_id} (joint error "
                                f"{second.final_error:.2f} rad, contacts {contacts})")
        report = ctx.MotionReport(first.duration + second.duration, second.final_error,
                                  first.unintended_contacts | second.unintended_contacts)
        return _result(report, target=obj_id, grasp_pos=grasp.pos.tolist(), candidates_tried=tried)

    @staticmethod
    def _plan(env, world, body: str, grasp: Pose, grip, ik_restarts: int | None = None):
        """The move to the pre-grasp pose (backed off along the approach) and the straight line in
        (``ik_restarts``: at most this many random restarts for the grasp and pre-grasp poses)."""
        if ik_restarts is not None and ik_restarts < world.ik_restarts:
            saved, world.ik_restarts = world.ik_restarts, ik_restarts
            try:
                return Approach._plan(env, world, body, grasp, grip)
            finally:
                world.ik_restarts = saved
        approach = grasp_approach(grasp)
        # A frame set deeper than the hand fits (the palm inside a tall object) is backed off along the
        # approach a little at a time, up to GRIP_BACKOFF and never so far that the pads miss the object.
        reach = min(GRIP_BACKOFF, _pad_overlap(env, body, grasp, grip) - PAD_OVERLAP)  # -inf: nothing seen
        for backoff in [0.0, *(np.arange(0.01, reach + 1e-9, 0.01) if reach >= 0.01 else [])]:
            goal = PoseGoal(Pose(grasp.pos - approach * backoff, grasp.quat), 0.004, 0.05)
            world.allow_contact([body])
            q_grasp = world.inverse_kinematics(goal)
            if _touches_lightly(world, [q_grasp]):
                break
        else:
            raise PlanningError(f"the open fingers would pierce the target at {np.round(grasp.pos, 3).tolist()}")
        # From above, a pre-grasp higher over the object (the arm clear of tall neighbours) when the usual one
        # fails; the move in is always straight along the approach.
        backs = (PRE_GRASP, PRE_GRASP_HIGH) if approach[2] < -0.9 else (PRE_GRASP,)
        for k, back in enumerate(backs):
            try:
                pre = PoseGoal(Pose(goal.pose.pos - approach * back, grasp.quat), 0.005, 0.05)
                world.allow_contact([])
                q_pre = world.inverse_kinematics(pre, seeds=q_grasp[None])
                world.allow_contact([body])
                down = ctx.planner(env, "straight_line").plan(q_pre, goal, world)
                if not _touches_lightly(world, down.q):
                    raise PlanningError("the descent would push the fingers through the target")
                break
            except PlanningError:
                if k == len(backs) - 1:
                    raise
        world.allow_contact([])
        to_pre = ctx.planner(env, "ompl").plan(env.arm_q(), JointGoal(q_pre), world)
        return to_pre, down


def _fingers_open(env, command: float, grip) -> bool:
    """Whether the hand is already fully open (``command`` -1), the fingers at rest there."""
    if command != -1.0 or env.gripper_command != -1.0 or ctx.pad_gap(env) < grip.open_gap - FINGERS_OPEN_SLACK:
        return False
    m = env.model
    dofs = [m.jnt_dofadr[m.joint(j).id] for j in env.names.gripper_joints]
    return float(np.max(np.abs(env.data.qvel[dofs]), initial=0.0)) < FINGERS_STILL


def _pad_overlap(env, body: str, grasp: Pose, grip) -> float:
    """How far the object reaches back towards the hand from the pads' middle in ``grasp`` (a grip-site pose),
    counting only the parts of it between the pads: backing the grasp off by more than this misses the object.

    Rays along the approach through the space between the open pads find the object's surface nearest the hand.
    """
    import mujoco

    m, d = env.model, env.data
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, grasp.quat)
    rot = rot.reshape(3, 3)
    centre = grasp.pos + rot @ grip.open_centre
    closing, approach = rot @ grip.closing, rot @ grip.approach
    across = np.cross(approach, closing)
    target = m.body(body).id
    groups = np.zeros(6, dtype=np.uint8)
    groups[3] = 1  # object collision geoms
    hit = np.zeros(1, dtype=np.int32)
    start_back = 0.15
    best = -np.inf
    for u in np.linspace(-0.4, 0.4, 5) * grip.open_gap:
        for v in (-PAD_HALF_WIDTH, 0.0, PAD_HALF_WIDTH):
            origin = centre - approach * start_back + closing * u + across * v
            t = mujoco.mj_ray(m, d, origin, approach, groups, 0, -1, hit)
            if t >= 0 and m.geom_bodyid[hit[0]] == target:
                best = max(best, start_back - t)
    return best


def _touches_lightly(world, qs) -> bool:
    """True when no configuration in ``qs`` brings the robot within ``TARGET_TOUCH`` of anything, target
    included (allowances off)."""
    saved = world.clearance
    world.allow_contact([])
    world.clearance = TARGET_TOUCH
    try:
        return all(world.is_valid(q) for q in qs)
    finally:
        world.clearance = saved


class Lift(PrimitiveAction):
    """Raise the hand (and what it holds) straight up by ``height`` metres (default 0.15)."""

    params = (Param("height", "number", low=0.01, high=0.4, doc="metres"),)

    def execute(self, env) -> ActionResult:
        height = float(self.arguments.get("height", 0.15))
        held = env.held_object
        world = ctx.collision_world(env)
        own = set(world.robot_bodies)
        if env.held_object is not None:
            own.add(env.model.body(env.names.objects[env.held_object]).id)
        support = ctx.touching_bodies(env, own)  # what it rests on may be touched while leaving it
        world.allow_contact(support)
        # So may what the hand or the held object already overlaps within the planning clearance (a neighbour
        # leaning on it, a tray rim under a wine glass's foot): rising can only move away from it.
        m = env.model
        for pair in world.contacts(env.arm_q()):
            support |= {m.body(name).id for name in pair if m.body(name).id not in own}
        world.allow_contact(support)
        pose = env.ee_pose()
        goal = PoseGoal(Pose(pose.pos + [0.0, 0.0, height], pose.quat), 0.005, 0.05)
        try:
            trajectory = ctx.planner(env, "straight_line").plan(env.arm_q(), goal, world)
        except PlanningError as e:
            # Near a joint limit or singularity the straight line breaks off: clear the support by a short
            # straight rise, then plan freely to the raised pose.
            logger.info("straight lift failed (%s); rising 3 cm and planning the rest", e)
            rise = PoseGoal(Pose(pose.pos + [0.0, 0.0, min(height, 0.03)], pose.quat), 0.005, 0.05)
            try:
                first = ctx.planner(env, "straight_line").plan(env.arm_q(), rise, world)
            except PlanningError:
                # Something overhangs the object (a tray's flared rim over a glass's foot): plan the whole way,
                # sideways first where needed, touching only the support.
                q_goal = self._raised(env, world, goal)
                trajectory = ctx.planner(env, "ompl").plan(env.arm_q(), JointGoal(q_goal), world)
                return self._checked(env, ctx.execute(env, trajectory, world, allowed=support), held, height)
            report = ctx.execute(env, first, world, allowed=support)
            world = ctx.collision_world(env)
            q_goal = self._raised(env, world, goal)
            trajectory = ctx.planner(env, "ompl").plan(env.arm_q(), JointGoal(q_goal), world)
            second = ctx.execute(env, trajectory, world)
            report = ctx.MotionReport(report.duration + second.duration, second.final_error,
                                      report.unintended_contacts | second.unintended_contacts)
            return self._checked(env, report, held, height)
        report = ctx.execute(env, trajectory, world, allowed=support)
        return self._checked(env, report, held, height)

    @staticmethod
    def _checked(env, report: ctx.MotionReport, held: int | None, height: float) -> ActionResult:
        """Lifting an object succeeds only when it ends held and clear of every support."""
        result = _result(report, env, held, height=height)
        if result.success and held is not None and not env.is_lifted(held):
            result.success = False
            result.failure_reason = f"object {held} is still supported after lifting (caught on something)"
        return result


    @staticmethod
    def _raised(env, world, goal: PoseGoal) -> np.ndarray:
        """An arm configuration for the raised pose, or, where something overhangs it (a bowl stacked on a
        neighbour, its rim over the object), for the nearest pose beside it at the same height."""
        reasons = []
        for dx, dy in LIFT_SIDESTEPS:
            shifted = PoseGoal(Pose(goal.pose.pos + [dx, dy, 0.0], goal.pose.quat), goal.position_tolerance,
                               goal.orientation_tolerance)
            try:
                return world.inverse_kinematics(shifted, seeds=env.arm_q()[None])
            except PlanningError as e:
                reasons.append(e)
        raise reasons[0]


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
        table = ctx.table(env)
        snap = env.snapshot()
        try:
            rise = placement.clear_start(env, ctx.collision_world(env))
            world = ctx.collision_world(env)
            support_body, support_top, places = self._places(env, target, held, table)
            places = rotated(places, attempt)
            to_above, down = self._plan(env, world, target, places, support_body, support_top)
        except PlanningError:
            env.restore(snap)
            raise
        result = self._put_down(env, world, to_above, down, support_body, held_body, held)
        result.info["unintended_contacts"] = sorted(set(result.info["unintended_contacts"])
                                                    | (rise.unintended_contacts if rise else set()))
        return result

    @staticmethod
    def _places(env, target, held, table):
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

    @staticmethod
    def _plan(env, world, target, places, support_body, support_top):
        reasons = []
        hand = env.ee_pose().pos
        # Where a neighbour blocks the last centimetres of the descent (fingers beside a tall object), the
        # object is let go a little higher over the same place: a short drop still lands it. Onto an object,
        # the hand may also turn about the vertical (the held object with it) where it cannot go down as it is.
        yaws = CARRY_TURNS if isinstance(target, (int, np.integer)) else (0.0,)
        for xy, yaw, gap in itertools.product(places, yaws, RELEASE_GAPS):
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

    @staticmethod
    def _put_down(env, world, to_above, down, support_body, held_body, held) -> ActionResult:
        world.allow_contact([])
        first = ctx.execute(env, to_above, world)
        world = ctx.collision_world(env)
        world.allow_contact([support_body])
        second = ctx.execute(env, down.__class__(np.vstack([env.arm_q(), down.q[1:]]), down.t, down.joint_names),
                             world, allowed={support_body})
        # A thin part held (a rim, a handle, a stem) is let go with the hand opened only part way: opened fully,
        # the finger inside a rim would reach across to the far side and catch it on the way up.
        env.set_gripper(PRESHAPE_COMMANDS[0] if ctx.pad_gap(env) < THIN_HOLD else -1.0)
        env.hold(0.5)
        world = ctx.collision_world(env)
        # The opened fingers may now brush a neighbour: rising straight up can only leave it, so the plan may
        # start there; contacts in physics with anything but the released object still count.
        world.allow_contact([held_body])
        m = env.model
        near = {m.body(name).id for pair in world.contacts(env.arm_q()) for name in pair} - world.robot_bodies
        world.allow_contact({held_body} | near)
        pose = env.ee_pose()
        try:
            retreat = ctx.planner(env, "straight_line").plan(
                env.arm_q(), PoseGoal(Pose(pose.pos + [0.0, 0.0, 0.08], pose.quat), 0.005, 0.05), world)
            third = ctx.execute(env, retreat, world, allowed={held_body})
        except PlanningError as e:  # the object is down: the next move starts by rising clear of it
            logger.info("no straight retreat after letting go (%s); the hand stays where it released", e)
            third = ctx.MotionReport()
        env.hold(0.3)
        speed = float(np.linalg.norm(env.data.cvel[held_body][3:]))
        waited = 0.3
        while speed >= RESTING_SPEED and waited < REST_WAIT:
            # Something set down on a round or tilted base may rock a moment before it settles.
            env.hold(0.25)
            waited += 0.25
            speed = float(np.linalg.norm(env.data.cvel[held_body][3:]))
        contacts = first.unintended_contacts | second.unintended_contacts | third.unintended_contacts
        report = ctx.MotionReport(first.duration + second.duration + third.duration, third.final_error, contacts)
        result = _result(report, resting_speed=speed, released=env.held_object is None)
        result.success = env.held_object is None and speed < RESTING_SPEED
        if not result.success:
            result.failure_reason = f"object {held} did not come to rest (speed {speed:.3f} m/s)"
        return result


class MoveVel(PrimitiveAction):
    """Move the hand at ``velocity`` (vx, vy, vz in m/s, world frame) for ``duration`` seconds, continuously.

    The motion is a timed straight line (collision-checked like any other move) tracked by the physics loop;
    the measurement is the displacement actually travelled.
    """

    params = (Param("velocity", "vector", required=True, low=-0.5, high=0.5, length=3, doc="m/s, world frame"),
              Param("duration", "number", low=0.0, high=10.0, doc="s"))

    def execute(self, env) -> ActionResult:
        from muble import get_registry

        velocity = np.asarray(self.arguments.get("velocity", (0.0, 0.0, 0.0)), dtype=float).reshape(3)
        duration = float(self.arguments.get("duration", 1.0))
        speed = float(np.linalg.norm(velocity))
        start = env.ee_pose()
        if speed * duration < 1e-4:
            env.hold(duration)
            return ActionResult(True, measurement=[0.0, 0.0, 0.0])
        world = ctx.collision_world(env)
        line = get_registry().create("planner", "straight_line", {"speed": speed, "max_distance": speed * duration + 0.01})
        goal = PoseGoal(Pose(start.pos + velocity * duration, start.quat), 0.003, 0.05)
        report = ctx.execute(env, line.plan(env.arm_q(), goal, world), world, settle=0.1)
        moved = env.ee_pose().pos - start.pos
        off = float(np.linalg.norm(moved - velocity * duration))
        info = {"duration": report.duration, "unintended_contacts": sorted(report.unintended_contacts)}
        if off > MOVE_VEL_TOLERANCE:
            return ActionResult(False, measurement=moved.tolist(), info=info,
                                failure_reason=f"the hand ended {off * 1000:.0f} mm from where the motion should "
                                               "have taken it (blocked)")
        return ActionResult(True, measurement=moved.tolist(), info=info)

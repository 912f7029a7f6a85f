"""The ``approach`` primitive: the open hand over an object by a planned move, then straight in to a grasp pose;
and its ``feasible`` check, which scene generation uses to keep only objects that can be picked and put back."""
from __future__ import annotations

import contextlib
import logging

import mujoco
import numpy as np

from muble import ActionResult, JointGoal, Param, PlanningError, Pose, PoseGoal, PrimitiveAction, SceneGraph
from muble.core.params import argument
from muble.core.symbolic import ArmState, set_flag
from muble.stage.geometry import mujoco_quat_matrix
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import tolerances as tol
from muble_plugins.primitives.common import ATTEMPT, PART_OPEN, checked_result, rotated
from muble_plugins.primitives.grasping import PAD_MARGIN, PRE_GRASP, grasp_approach, grasp_candidates, hand_clearance

logger = logging.getLogger(__name__)


class Approach(PrimitiveAction):
    """Bring the open hand into the grasp pose of an object: over it by a planned move, then straight in.

    Candidates come from the object's grasp frames (``grasp_candidates``). One is taken when its grasp pose and
    its straight descent are collision-free, the open fingers included: the target itself may only be touched
    within ``TARGET_TOUCH`` (the pads brushing it), never pierced, so that closing really pinches it.
    """

    params = (Param("target", "object", required=True), ATTEMPT)
    hand_at_target = "grasp"

    def execute(self, env) -> ActionResult:
        attempt = int(argument(self, "attempt"))
        obj_id, body, snap, grip = self._start(env)
        reasons, tried = [], 0
        for command in HAND_OPENINGS:
            try:
                world, candidates = candidates_with_opening(env, obj_id, body, command)
            except PlanningError:
                env.restore(snap)
                raise
            candidates = rotated(candidates, attempt)[:EXECUTE_CANDIDATES]
            tried += len(candidates)
            chosen = first_short_swing(env, world, body, candidates, grip, reasons)
            if chosen is not None:
                return _go(env, snap, obj_id, body, *chosen, len(reasons) + 1)
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
        obj_id, body, snap, grip = self._start(env)
        reasons, tried = [], 0
        try:
            for command in HAND_OPENINGS:
                if reasons and all("out of reach" in r for r in reasons):
                    break  # a narrower hand reaches no farther
                world, candidates = candidates_with_opening(env, obj_id, body, command,
                                                            settle=not _fingers_open(env, command, grip),
                                                            limit=FEASIBLE_CANDIDATES)
                for grasp in candidates[:FEASIBLE_CANDIDATES]:
                    tried += 1
                    try:
                        _, down = plan_grasp(env, world, body, grasp, grip, FEASIBLE_IK_RESTARTS, move=False)
                        _rise_holding(env, world, body, down.q[-1])
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

    def _start(self, env):
        """(target id, its body name, a snapshot to restore, the gripper's geometry); raises ``PlanningError``
        when the hand already holds something."""
        obj_id = int(self.arguments["target"])
        body = ctx.body_name(env, obj_id)
        if env.held_object is not None:
            raise PlanningError(f"the hand already holds object {env.held_object}; lower it before approaching")
        return obj_id, body, env.snapshot(), ctx.grip_geometry(env)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The empty hand, hovering over the target, comes down into its grasp pose."""
        hand = ArmState.of(scene)
        target = scene.object(int(self.arguments["target"]))
        if hand.held is not None or hand.over != target.id:
            return ActionResult(False, failure_reason="move over an object with an empty gripper before approaching it")
        set_flag(scene, "approached", target)
        set_flag(scene, "gripper_over", None)
        return ActionResult(True)


# Hand openings tried in turn, as gripper commands (-1 open, 1 closed): fully open first (every grasp that fits
# the gripper), then part way, which may fit in clutter where the open hand touches something, or next to the
# object's own handle.
HAND_OPENINGS = (-1.0, PART_OPEN)
PRESHAPE_SETTLE = 0.5  # s for the fingers to reach a part-way opening (the fully open hand gets 0.3 s)
# m the part-way opening may still close while the arm moves: taken off the widest part it is offered, so that
# the part still fits when the fingers have closed that much.
PRESHAPE_SLACK = 0.002


def candidates_with_opening(env, obj_id: int, body: str, command: float, settle: bool = True,
                            limit: int | None = None):
    """The collision world and the ranked grasp candidates with the hand opened by ``command`` (one of
    ``HAND_OPENINGS``), the first ``limit`` of them only when given. The fingers are moved there in physics
    (``settle=False``: they already are)."""
    model = env.object_models[obj_id]
    grip = ctx.grip_geometry(env)
    table = env.table()
    if settle:
        env.set_gripper(command)
        env.hold(tol.SETTLE if command == -1.0 else PRESHAPE_SETTLE)
    if command == -1.0:
        max_width = grip.max_width  # the fingers go on opening on the way; the measured open gap applies
    else:
        max_width = ctx.pad_gap(env) - 2 * PAD_MARGIN - PRESHAPE_SLACK
    world = env.collision_world()
    # Ranked by how far the hand stays from the neighbours, with more directions around round objects.
    candidates = grasp_candidates(env.object_pose(obj_id), model, table.top_z, max_width=max_width,
                                  rest_quat=env.top_down(), grip=grip,
                                  clearance=hand_clearance(world, body, ignore=[table.body]), limit=limit)
    if not candidates and command == -1.0:
        raise PlanningError(f"object {obj_id} ({model.spec.category}) has no grasp that fits this gripper "
                            f"(parts {grip.closed_gap * 1000:.0f}-{grip.max_width * 1000:.0f} mm thick); "
                            "choose another robot.gripper or object")
    return world, candidates


# rad any arm joint travels to a pre-grasp pose beyond which other grasps are looked for first: 2 rad (115 deg),
# the wrist turned most of the way to another branch of the arm's configurations.
LONG_SWING = 2.0
SWING_ALTERNATIVES = 6  # candidates tried for a nearer grasp once one with a long swing was found: a few, not all


def first_short_swing(env, world, body: str, candidates: list, grip, reasons: list[str]):
    """(move to the pre-grasp pose, straight line in, grasp) of the first candidate that plans with no joint
    swinging more than ``LONG_SWING``; failing that, the first that plans at all, once ``SWING_ALTERNATIVES`` more
    candidates were tried for a nearer one. ``None`` when none plans; each failure's reason goes to ``reasons``.

    A grasp whose arm configuration lies on another branch (wrist turned most of a turn) is kept back: on such a
    long swing the wrist lags and the hand sweeps where the plan did not go.
    """
    swing, after_swing = None, 0
    for grasp in candidates:
        try:
            to_pre, down = plan_grasp(env, world, body, grasp, grip)
        except PlanningError as e:
            reasons.append(str(e))
        else:
            if np.max(np.abs(to_pre.q[-1] - to_pre.q[0])) <= LONG_SWING:
                return to_pre, down, grasp
            swing = swing or (to_pre, down, grasp)
        if swing is not None:
            after_swing += 1
            if after_swing == SWING_ALTERNATIVES:
                break
    return swing


# rad any arm joint may lag the pre-grasp configuration before the descent (about 3 deg): more and the hand would
# meet the object turned; the same bound holds for the straight move in, where more means it was stopped.
PRE_GRASP_TRACKING = 0.05
PRE_GRASP_RETRIES = 2  # planned moves again to the pre-grasp configuration while the arm lags it


def _go(env, snap, obj_id: int, body: str, to_pre, down, grasp: Pose, tried: int) -> ActionResult:
    """Execute the planned approach: over the object, then (the empty hand tared) straight in."""
    world = env.collision_world()
    first = ctx.execute(env, to_pre, world)
    env.hold(tol.SETTLE)
    first = _catch_up(env, world, to_pre.q[-1], first)
    lag = _lag(env, to_pre.q[-1])
    if lag > PRE_GRASP_TRACKING:
        env.restore(snap)
        raise PlanningError(f"the arm did not reach the pre-grasp pose over object {obj_id} "
                            f"(joint error {lag:.2f} rad)")
    env.tare()  # the empty hand, still: the zero for weighing
    world = env.collision_world()
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
    return checked_result(report, target=obj_id, grasp_pos=grasp.pos.tolist(), candidates_tried=tried)


def _lag(env, q_pre: np.ndarray) -> float:
    """How far the arm is from the pre-grasp configuration (rad, worst joint)."""
    return float(np.max(np.abs(env.arm_q() - q_pre)))


def _catch_up(env, world, q_pre: np.ndarray, report: ctx.MotionReport) -> ctx.MotionReport:
    """Up to ``PRE_GRASP_RETRIES`` planned moves again to ``q_pre`` while the arm lags it by more than
    ``PRE_GRASP_TRACKING``; the report of the last move made. A long swing can leave a weak wrist joint far behind
    its set-point (the other joints' motion drags it); descending from there would meet the object with the hand
    turned."""
    for _ in range(PRE_GRASP_RETRIES):
        if _lag(env, q_pre) <= PRE_GRASP_TRACKING:
            break
        world.allow_contact([])
        report = ctx.execute(env, ctx.long_move_planner(env).plan(env.arm_q(), JointGoal(q_pre), world), world)
        env.hold(tol.SETTLE)
    return report


# Clearance (m) the open hand keeps from the target in the grasp pose and on the way in: the fingers must
# not already press on it, or closing would not pinch it between the pads. 1 mm lets the pads brush it.
TARGET_TOUCH = 0.001
# m a grasp may be moved back along its approach to clear the target, in 1 cm steps: a frame set deeper than the
# hand fits (the palm inside a tall object) needs a little.
GRIP_BACKOFF = 0.03
PAD_OVERLAP = 0.004  # m the pads' middle stays inside the object when a grasp is backed off
PRE_GRASP_HIGH = 0.18  # m above a top-down grasp for the second pre-grasp tried: the arm clear of tall neighbours


def plan_grasp(env, world, body: str, grasp: Pose, grip, ik_restarts: int | None = None, move: bool = True):
    """The move to the pre-grasp pose (backed off along the approach) and the straight line in
    (``ik_restarts``: at most this many random restarts for the grasp and pre-grasp poses). ``move=False``: the
    move is only checked (``MotionPlanner.check``, the same outcome) and ``None`` stands in its place."""
    with _fewer_ik_restarts(world, ik_restarts):
        goal, q_grasp = _backed_off_grasp(env, world, body, grasp, grip)
        q_pre, down = _pre_grasp(env, world, body, grasp, goal, q_grasp)
        world.allow_contact([])
        planner = ctx.long_move_planner(env)
        if not move:
            planner.check(env.arm_q(), JointGoal(q_pre), world)
            return None, down
        return planner.plan(env.arm_q(), JointGoal(q_pre), world), down


@contextlib.contextmanager
def _fewer_ik_restarts(world, ik_restarts: int | None):
    """``world.ik_restarts`` lowered to ``ik_restarts`` for the block (never raised; ``None``: unchanged)."""
    if ik_restarts is None or ik_restarts >= world.ik_restarts:
        yield
        return
    saved, world.ik_restarts = world.ik_restarts, ik_restarts
    try:
        yield
    finally:
        world.ik_restarts = saved


def _backed_off_grasp(env, world, body: str, grasp: Pose, grip) -> tuple[PoseGoal, np.ndarray]:
    """The grasp pose goal and its arm configuration: ``grasp`` itself, else moved back along its approach 1 cm at
    a time, up to ``GRIP_BACKOFF`` and never so far that the pads keep less than ``PAD_OVERLAP`` of the object,
    the first where the open hand touches the target only lightly (``TARGET_TOUCH``)."""
    approach = grasp_approach(grasp)
    reach = min(GRIP_BACKOFF, _pad_overlap(env, body, grasp, grip) - PAD_OVERLAP)  # -inf: nothing seen
    for backoff in [0.0, *(np.arange(0.01, reach + 1e-9, 0.01) if reach >= 0.01 else [])]:
        goal = PoseGoal(Pose(grasp.pos - approach * backoff, grasp.quat), *tol.CONTACT)
        world.allow_contact([body])
        q_grasp = world.inverse_kinematics(goal)
        if _touches_lightly(world, [q_grasp]):
            return goal, q_grasp
    raise PlanningError(f"the open fingers would pierce the target at {np.round(grasp.pos, 3).tolist()}")


def _pre_grasp(env, world, body: str, grasp: Pose, goal: PoseGoal, q_grasp: np.ndarray):
    """(pre-grasp configuration, straight line from it in to ``goal``): ``PRE_GRASP`` back along the approach,
    else, from above, ``PRE_GRASP_HIGH`` over the object (the arm clear of tall neighbours); the error of the last
    tried when none works."""
    approach = grasp_approach(grasp)
    backs = (PRE_GRASP, PRE_GRASP_HIGH) if approach[2] < -0.9 else (PRE_GRASP,)
    for k, back in enumerate(backs):
        try:
            pre = PoseGoal(Pose(goal.pose.pos - approach * back, grasp.quat), *tol.FREE)
            world.allow_contact([])
            q_pre = world.inverse_kinematics(pre, seeds=q_grasp[None])
            world.allow_contact([body])
            down = ctx.straight_line_planner(env).plan(q_pre, goal, world)
            if not _touches_lightly(world, down.q):
                raise PlanningError("the descent would push the fingers through the target")
            return q_pre, down
        except PlanningError:
            if k == len(backs) - 1:
                raise


PAD_HALF_WIDTH = 0.006  # m: the part of an object between the pads, across the closing direction


def _pad_overlap(env, body: str, grasp: Pose, grip) -> float:
    """How far the object reaches back towards the hand from the pads' middle in ``grasp`` (a grip-site pose),
    counting only the parts of it between the pads: backing the grasp off by more than this misses the object.

    Rays along the approach through the space between the open pads find the object's surface nearest the hand.
    """
    m, d = env.model, env.data
    rot = mujoco_quat_matrix(grasp.quat)
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


# Feasibility check (scene generation): how much of ``execute``'s search it repeats, traded against its cost.
FEASIBLE_CANDIDATES = 16  # grasp candidates per hand opening tried at most
# Grasp candidates per hand opening ``execute`` tries at most (from the ``attempt``-th on): three times the number
# the reach check vouches for. A round object in clutter offers hundreds; when the first few dozen are all
# blocked the rest are too (the same neighbour in the way), and planning each takes seconds.
EXECUTE_CANDIDATES = 48
FEASIBLE_IK_RESTARTS = 12  # random inverse-kinematics restarts per pose (``execute`` uses the world's default)
FEASIBLE_RISE = 0.10  # m the hand must rise straight up holding the object: clear of its support, as ``lift`` does
FINGERS_STILL = 0.005  # m/s (rad/s) of finger joint speed below which the fingers count as at rest
FINGERS_OPEN_SLACK = 0.003  # m the pads may still lack of the measured open gap for the hand to count as open


def _rise_holding(env, world, body: str, q_grasp: np.ndarray) -> None:
    """Raise ``PlanningError`` unless, holding ``body`` at ``q_grasp``, the hand rises ``FEASIBLE_RISE``
    straight up touching only what the object stands on or already overlaps (as ``lift`` allows)."""
    m = world.model
    world.kinematics.set_q(q_grasp)
    world.hold(body)
    held = m.body(body).id
    support = {env.table().body}
    world.allow_contact(support)
    support |= {m.body(name).id for pair in world.contacts(q_grasp) for name in pair} - world.robot_bodies - {held}
    world.allow_contact(support)
    pose = world.ee_pose(q_grasp)
    goal = PoseGoal(Pose(pose.pos + [0.0, 0.0, FEASIBLE_RISE], pose.quat), *tol.FREE)
    ctx.straight_line_planner(env).plan(q_grasp, goal, world)


def _fingers_open(env, command: float, grip) -> bool:
    """Whether the hand is already fully open (``command`` -1), the fingers at rest there: no need to settle."""
    if command != -1.0 or env.gripper_command != -1.0 or ctx.pad_gap(env) < grip.open_gap - FINGERS_OPEN_SLACK:
        return False
    m = env.model
    dofs = [m.jnt_dofadr[m.joint(j).id] for j in env.names.gripper_joints]
    return float(np.max(np.abs(env.data.qvel[dofs]), initial=0.0)) < FINGERS_STILL

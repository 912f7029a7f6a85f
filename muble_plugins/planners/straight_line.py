"""Straight-line Cartesian motion for short moves (approach, lift, lower): the hand travels along a line.

Each waypoint's IK starts from the previous solution, so the arm moves continuously; a jump in joint space
(the solver found another branch) or a waypoint in collision ends planning with a ``PlanningError``.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from muble import CollisionWorld, JointGoal, MotionPlanner, PlanningError, Pose, PoseGoal, Trajectory
from muble.core.ranges import configured

logger = logging.getLogger(__name__)


@dataclass
class StraightLinePlannerConfig:
    """Options of the straight-line Cartesian planner."""

    step: float = 0.005  # m between IK waypoints along the line
    rotation_step: float = 0.05  # rad between IK waypoints when the hand turns
    max_joint_jump: float = 0.3  # rad: a larger change between two waypoints is a branch switch, not a line
    max_distance: float = 0.5  # m: longer moves belong to a sampling-based planner
    speed: float = 0.15  # m/s of the hand
    max_velocity: float = 1.0  # rad/s per joint
    position_tolerance: float = 0.002  # m per waypoint
    orientation_tolerance: float = 0.02  # rad per waypoint


def _slerp(q0: np.ndarray, q1: np.ndarray, f: float) -> np.ndarray:
    dot = float(np.dot(q0, q1))
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + f * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = np.arccos(dot)
    return (np.sin((1 - f) * theta) * q0 + np.sin(f * theta) * q1) / np.sin(theta)


class StraightLinePlanner(MotionPlanner):
    """Moves the end effector along a straight line (position) with slerped orientation.

    Needs a world with ``ee_pose(q) -> Pose`` (``MujocoCollisionWorld`` has it). A ``JointGoal`` is followed
    as a straight line in joint space instead. Built from a ``StraightLinePlannerConfig`` and/or keyword overrides of
    its fields, checked as ``OmplPlanner``'s are.
    """

    def __init__(self, config: StraightLinePlannerConfig | None = None, **options):
        self.config = configured(StraightLinePlannerConfig, config, options, owner="planner 'straight_line'")
        self.last_planning_time = 0.0

    def plan(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> Trajectory:
        began = time.perf_counter()
        start_q = np.asarray(start_q, dtype=float)
        if isinstance(goal, JointGoal):
            path = self._joint_line(start_q, np.asarray(goal.q, dtype=float), world)
            hand_distances = None
        else:
            path, hand_distances = self._cartesian_line(start_q, goal, world)
        self.last_planning_time = time.perf_counter() - began
        return self._timed(path, hand_distances, tuple(world.joint_names))

    def _joint_line(self, start_q: np.ndarray, goal_q: np.ndarray, world: CollisionWorld) -> np.ndarray:
        n = max(1, int(np.ceil(np.max(np.abs(goal_q - start_q)) / 0.02)))
        path = np.array([start_q + (goal_q - start_q) * (i / n) for i in range(n + 1)])
        for i, q in enumerate(path[1:], 1):
            if not world.is_valid(q):
                raise PlanningError(self._blocked(world, i / n))
        return path

    def _cartesian_line(self, start_q: np.ndarray, goal: PoseGoal, world: CollisionWorld):
        try:
            start: Pose = world.ee_pose(start_q)
        except NotImplementedError:
            raise PlanningError(f"the straight-line planner needs a world with ee_pose(q); {type(world).__name__} "
                                "has none: use the 'ompl' planner") from None
        distance = float(np.linalg.norm(goal.pose.pos - start.pos))
        if distance > self.config.max_distance:
            raise PlanningError(f"straight-line move of {distance:.2f} m exceeds max_distance "
                                f"{self.config.max_distance:.2f} m; use the 'ompl' planner for long moves")
        dot = min(1.0, abs(float(np.dot(start.quat, goal.pose.quat))))
        angle = 2.0 * np.arccos(dot)
        n = max(1, int(np.ceil(max(distance / self.config.step, angle / self.config.rotation_step))))
        # IK from the previous configuration alone keeps the arm on its current branch.
        path = [start_q]
        q = start_q
        for i in range(1, n + 1):
            f = i / n
            last = i == n
            target = PoseGoal(
                Pose(start.pos + f * (goal.pose.pos - start.pos), _slerp(start.quat, goal.pose.quat, f)),
                goal.position_tolerance if last else self.config.position_tolerance,
                goal.orientation_tolerance if last else self.config.orientation_tolerance,
            )
            try:
                q_next = world.local_inverse_kinematics(target, q)
            except PlanningError as e:
                raise PlanningError(f"straight line blocked at {f:.0%} of the way: {e}") from None
            jump = float(np.max(np.abs(q_next - q)))
            if jump > self.config.max_joint_jump:
                raise PlanningError(f"straight line needs a joint jump of {jump:.2f} rad at {f:.0%} of the way "
                                    "(singularity or joint limit); use the 'ompl' planner for this move")
            path.append(q_next)
            q = q_next
        return np.array(path), np.full(n, distance / n)

    @staticmethod
    def _blocked(world: CollisionWorld, fraction: float) -> str:
        contacts = world.last_contacts
        return f"straight line blocked at {fraction:.0%} of the way by contact {contacts[:3]}; use the 'ompl' planner"

    def _timed(self, path: np.ndarray, hand_distances: np.ndarray | None, names: tuple[str, ...]) -> Trajectory:
        if len(path) == 1:
            return Trajectory(path, np.array([0.0]), names)
        joint_steps = np.max(np.abs(np.diff(path, axis=0)), axis=1)
        dt = joint_steps / self.config.max_velocity
        if hand_distances is not None:
            dt = np.maximum(dt, hand_distances / self.config.speed)
        dt = np.maximum(dt, 1e-3)
        # Ease in and out over the first and last few waypoints so the hand starts and stops smoothly.
        ramp = min(5, len(dt) // 2)
        for k in range(ramp):
            scale = (ramp + 1) / (k + 1)
            dt[k] *= scale
            dt[-1 - k] *= scale
        return Trajectory(path, np.concatenate(([0.0], np.cumsum(dt))), names)

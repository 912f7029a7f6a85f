"""Joint-space sampling-based planning with OMPL (RRTConnect by default), path simplification and timing."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from muble import (CollisionWorld, ConfigError, JointGoal, MotionPlanner, PlanningError, PoseGoal, Trajectory,
                   bounded)
from muble.core.errors import unknown_name
from muble.core.ranges import configured
from muble_plugins.planners.timing import time_parameterise

logger = logging.getLogger(__name__)

# OMPL geometric planners that solve a single query from one start to one goal state.
OMPL_PLANNERS = ("RRTConnect", "RRT", "RRTstar", "InformedRRTstar", "SORRTstar", "AORRTC", "BITstar", "KPIECE1",
                 "BKPIECE1", "LBKPIECE1", "PRM", "PRMstar", "FMT", "BFMT")


@dataclass
class OmplPlannerConfig:
    """Options of the OMPL joint-space planner."""

    planner: str = "RRTConnect"  # any name in OMPL_PLANNERS
    # Planning work before PlanningError, counted in collision checks (states and motion steps), not seconds:
    # a query ends the same way on an idle and on a saturated machine.
    check_budget: int = bounded(10_000, ge=1)
    time_limit: float = bounded(60.0, gt=0)  # s: only a safety cap against a runaway query
    simplify: bool = True  # shorten the raw path (vertex reduction and shortcuts)
    check_step: float = bounded(0.02, gt=0)  # rad: largest joint step between two collision checks along a motion
    max_velocity: float = bounded(1.0, gt=0)  # rad/s per joint
    max_acceleration: float = bounded(2.0, gt=0)  # rad/s^2 per joint
    sample_period: float = bounded(0.02, gt=0)  # s between trajectory samples
    try_direct: bool = True  # first check the straight joint-space segment; plan only if it is blocked
    # OMPL's random seed, reset before every query so that a query always gives the same path
    seed: int = bounded(1, ge=0)


class OmplPlanner(MotionPlanner):
    """Plans in joint space against ``world.is_valid``; a pose goal is turned into joints with the world's IK.

    Built from an ``OmplPlannerConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``OmplPlanner(try_direct=False)``), checked against the schema's types and bounds.
    """

    def __init__(self, config: OmplPlannerConfig | None = None, **options):
        self.config = configured(OmplPlannerConfig, config, options, owner="planner 'ompl'")
        if self.config.planner not in OMPL_PLANNERS:
            raise ConfigError(unknown_name("OMPL planner", self.config.planner, OMPL_PLANNERS))
        self.last_planning_time = 0.0
        self.last_used_sampling = False

    # The validity of every state along a segment, at most ``check_step`` apart.
    def segment_valid(self, world: CollisionWorld, a: np.ndarray, b: np.ndarray) -> bool:
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / self.config.check_step)))
        return all(world.is_valid(a + (b - a) * (i / n)) for i in range(1, n + 1))

    def resolve_goal(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> np.ndarray:
        if isinstance(goal, JointGoal):
            q = np.asarray(goal.q, dtype=float)
            if not world.is_valid(q):
                contacts = world.last_contacts
                raise PlanningError(f"goal configuration is in collision or outside the joint limits {contacts[:3]}; "
                                    "choose another goal")
            return q
        return world.inverse_kinematics(goal, seeds=np.asarray(start_q, dtype=float)[None])

    def plan(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> Trajectory:
        path = self._path(start_q, goal, world, self.config.simplify)
        names = tuple(world.joint_names)
        return time_parameterise(path, self.config.max_velocity, self.config.max_acceleration,
                                 self.config.sample_period, names)

    def check(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld) -> None:
        """``plan``'s outcome without its last steps: simplifying a path found and timing it never fail (OMPL's
        random generators are seeded again before every query, so no later query changes either)."""
        self._path(start_q, goal, world, simplify=False)

    def _path(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld,
              simplify: bool) -> np.ndarray:
        start_q = np.asarray(start_q, dtype=float)
        # A held object may start against what it rests on or leans on (not the arm): the path may leave it.
        with world.resting_at(start_q) as valid:
            if not valid:
                contacts = world.last_contacts
                raise PlanningError(f"start configuration is in collision {contacts[:3]}; move the arm clear "
                                    "first (e.g. a straight-line retreat) or allow the contact")
            return self._plan(start_q, goal, world, simplify)

    def _plan(self, start_q: np.ndarray, goal: JointGoal | PoseGoal, world: CollisionWorld,
              simplify: bool) -> np.ndarray:
        began = time.perf_counter()
        goal_q = self.resolve_goal(start_q, goal, world)
        self.last_used_sampling = False
        if self.config.try_direct and self.segment_valid(world, start_q, goal_q):
            path = np.array([start_q, goal_q])
        else:
            self.last_used_sampling = True
            path = self._sample_path(start_q, goal_q, world, simplify)
        self.last_planning_time = time.perf_counter() - began
        logger.debug("planned %d waypoints in %.1f ms", len(path), self.last_planning_time * 1e3)
        return path

    def _sample_path(self, start_q: np.ndarray, goal_q: np.ndarray, world: CollisionWorld,
                     simplify: bool) -> np.ndarray:
        import ompl.base as ob
        import ompl.geometric as og
        import ompl.util as ou

        # Re-seeding OMPL before each query makes every plan a function of its inputs alone, whatever was
        # planned before in this process (OMPL complains that sampling has started: silenced, it is intended).
        ou.setLogLevel(ou.LOG_NONE)
        ou.RNG.setSeed(max(1, int(self.config.seed)))
        ou.setLogLevel(ou.LOG_WARN)  # OMPL logs every solve at INFO on stdout
        limits = world.joint_limits
        dof = len(limits)
        space = ob.RealVectorStateSpace(dof)
        bounds = ob.RealVectorBounds(dof)
        for i, (lo, hi) in enumerate(limits):
            bounds.setLow(i, float(lo))
            bounds.setHigh(i, float(hi))
        space.setBounds(bounds)
        setup = og.SimpleSetup(space)

        checks = [0]

        def valid(state) -> bool:
            checks[0] += 1
            return bool(world.is_valid(np.fromiter((state[i] for i in range(dof)), float, dof)))

        setup.setStateValidityChecker(valid)
        info = setup.getSpaceInformation()
        # OMPL's resolution is a fraction of the space's largest extent; convert from radians.
        info.setStateValidityCheckingResolution(self.config.check_step / space.getMaximumExtent())
        setup.setPlanner(getattr(og, self.config.planner)(info))
        start, target = space.allocState(), space.allocState()
        for i in range(dof):
            start[i] = float(start_q[i])
            target[i] = float(goal_q[i])
        setup.setStartAndGoalStates(start, target)
        budget, deadline = self.config.check_budget, time.monotonic() + self.config.time_limit
        status = setup.solve(ob.PlannerTerminationCondition(
            lambda: checks[0] >= budget or time.monotonic() > deadline))
        logger.debug("OMPL %s: %s after %d collision checks", self.config.planner, status.asString(), checks[0])
        if not setup.haveExactSolutionPath():
            spent = (f"{self.config.time_limit:.1f} s (planner.time_limit)" if checks[0] < budget
                     else f"{budget} collision checks")
            raise PlanningError(
                f"no collision-free path found in {spent} ({status.asString()}); the goal may be enclosed by "
                "obstacles: clear the way or raise planner.check_budget"
            )
        path = setup.getSolutionPath()
        if simplify:
            # Vertex reduction then rope shortcutting: most of the gain of OMPL's full simplify() for a
            # fraction of the collision checks (each check is a Python call).
            simplifier = og.PathSimplifier(info)
            simplifier.reduceVertices(path)
            simplifier.ropeShortcutPath(path)
            simplifier.reduceVertices(path)
        states = path.getStates()
        return np.array([[s[i] for i in range(dof)] for s in states])

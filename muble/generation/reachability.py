"""The generator's reach check: the configured robot can grasp every pickupable object and put it down again.

The robot's environment is built for the scene as it will start, and the registered ``approach`` primitive is
asked, through ``PrimitiveAction.feasible``, whether each pickupable object has a grasp reached without
collision from the rest pose (the planned move over it and the straight move in: the same candidates, planner
and collision world that ``approach`` uses when it runs) from which the hand, holding the object, rises clear of
its support. Nothing is executed: only the arm's rest state and the fingers' opening are simulated.

It is a cheaper computation of the same decision, never an approximation: the environment is compiled without
what only a renderer sees (``visual=False``: the same bodies, collision geoms, masses and contacts, so every step,
ray and inverse kinematics gives the same numbers), the planner is built once, ``approach`` ranks only as many
grasp candidates as it tries, and inverse kinematics solves on the robot built without the objects (the same
iterates, bit for bit: ``MujocoCollisionWorld.solve_on_arm_alone``). ``tests/generation/test_reach_decisions.py``
holds the decisions of the check before these savings on 312 recorded layouts, reasons included;
``benchmarks/reach_check.py`` times both.
"""
from __future__ import annotations

import logging
import re
from typing import Any

from muble.core.errors import PlanningError
from muble.core.interfaces import MotionPlanner
from muble.core.objects import ObjectModel
from muble.core.scene import SceneGraph

log = logging.getLogger(__name__)

SETTLE = 0.5  # s of physics before the check, as before an episode (the fingers open, the objects at rest)
# m every object keeps from the robot at rest. On robosuite's stage the hand rests 0.4 m above the table, clear of
# the tallest object by 0.1 m; the original stage's rest pose holds the fingers 0.15 m above the table's middle,
# where an object under them is touched or pushed by the first move (measured: 3 of 40 layouts before this rule).
REST_CLEARANCE = 0.02
# A refusal's measured numbers (positions, distances, how far along a straight line it was blocked: decimals and
# percentages) depend on floating point's last bits, which differ between CPUs' instruction sets and which inverse
# kinematics' iterates amplify: the recording commit's own check, run on another machine, blocks a straight line at
# 19 % of the way instead of 15 %, the same object against the same neighbour. Counts and ids are exact.
_MEASURED = re.compile(r"-?\d+\.\d+(?:e-?\d+)?|\d+%")


def same_decision(a: str | None, b: str | None) -> bool:
    """Whether two reach-check decisions are the same: both accept (None), or both refuse for the same reason word
    for word (which object, which step failed, what collided, how many candidates were tried), its measured
    numbers aside (``_MEASURED``)."""
    if a is None or b is None:
        return a is b
    return _MEASURED.sub("#", a) == _MEASURED.sub("#", b)


def _too_near(env, scene: SceneGraph, when: str) -> str | None:
    """Why the nearest object closer than ``REST_CLEARANCE`` to the robot at rest is in the way, or ``None``."""
    from muble.sim.initial_state import robot_clearance

    near = robot_clearance(env, REST_CLEARANCE)
    if not near:
        return None
    obj = scene.object(min(near, key=near.__getitem__))
    x, y = (round(float(v), 3) for v in obj.position[:2])
    return (f"object {obj.id} ({obj.name}) at ({x}, {y}): {near[obj.id] * 1000:.0f} mm from the robot at rest, "
            f"{when} (less than {REST_CLEARANCE * 1000:.0f} mm)")


class ReachCheck:
    """``check(scene, models)`` -> ``None`` when every pickupable object can be grasped and put down again, else
    why not (the first object that cannot, with the primitive's reason).

    ``robot`` holds ``muble.app.config.RobotConfig`` fields (name, gripper …; empty: Panda); ``primitive`` is the
    registry name of the grasping primitive asked.
    """

    def __init__(self, robot: dict[str, Any] | None, primitive: str):
        self.robot = dict(robot or {}) or None
        self.primitive = primitive
        # Planners the primitive built for an environment (``Environment.cache``), handed to the next one: building
        # a planner validates its options, which costs more than a short plan, and a planner holds no state
        # between queries (each re-seeds its sampler).
        self._planners: dict[str, Any] = {}
        # The robot without the objects, by stage: inverse kinematics solves on it (``arm_alone``).
        self._arm_alone: dict[str, Any] = {}

    def __call__(self, scene: SceneGraph, models: dict[int, ObjectModel]) -> str | None:
        from muble.plugins.registry import get_registry
        from muble.sim.env import TabletopEnv

        registry = get_registry()
        # Physics and planning only: without what only a renderer sees the model compiles in half the time, and
        # every contact, ray, joint and step is the same (tests/generation/test_reach_decisions.py).
        env = TabletopEnv(scene, models, self.robot, {}, visual=False)
        env.cache.update(self._planners)
        self._solve_on_arm_alone(env)
        try:
            # Before settling too: an object inside the hand is pushed away while settling, yet was in its way.
            reason = _too_near(env, scene, "as built")
            if reason:
                return reason
            env.open_gripper()
            env.hold(SETTLE)  # as an episode starts: the hand open, the objects settled
            reason = _too_near(env, scene, "settled")
            if reason:
                return reason
            for obj in scene.objects:
                if not obj.pickupable:
                    continue
                try:
                    registry.create("primitive", self.primitive, {"target": obj.id}).feasible(env)
                except PlanningError as e:
                    x, y = (round(float(v), 3) for v in obj.position[:2])
                    return f"object {obj.id} ({obj.name}) at ({x}, {y}): {e}"
            return None
        finally:
            self._planners.update({k: v for k, v in env.cache.items() if isinstance(v, MotionPlanner)})
            env.close()

    def _solve_on_arm_alone(self, env) -> None:
        """Have ``env``'s collision world, whenever it is asked for, solve inverse kinematics on the same robot
        built without the objects (``MujocoCollisionWorld.solve_on_arm_alone``: the same iterates, bit for bit,
        where the robot's numbers are the same in both, checked each time; a fifth of a solve's time is MuJoCo
        placing the objects' geoms and sites, which the solver never reads)."""
        from muble.sim.env import TabletopEnv

        stage = env.names.stage
        model = self._arm_alone.get(stage)
        if model is None:
            alone = TabletopEnv(SceneGraph(), {}, {**(self.robot or {}), "stage": stage}, {}, visual=False)
            model = self._arm_alone[stage] = alone.model
            alone.close()
        built = env.collision_world

        def collision_world():
            world = built()
            world.solve_on_arm_alone(model)
            return world

        env.collision_world = collision_world

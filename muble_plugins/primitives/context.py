"""What the built-in primitives share on top of the environment API (``muble.core.environment.Environment``):
the gripper's measured geometry, the planners of long and straight moves, and trajectory execution with contact counting.

The collision world is the environment's own (a model copy, re-synced before every plan), so planning never
writes to the live simulation.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from muble import CollisionWorld, MotionPlanner, PlanningError, Pose, PoseGoal, Trajectory
from muble.core.environment import Environment
from muble.core.object_physics import CONTENTS_COLLISION_CLASS

from muble_plugins.primitives import tolerances as tol

logger = logging.getLogger(__name__)

HOVER = 0.12  # m between an object's top and the hand when moving above it

_grips_by_kind: dict[tuple, object] = {}


@dataclass
class MotionReport:
    """How a tracked motion went: duration, tracking error and unintended contacts seen in physics."""

    duration: float = 0.0
    final_error: float = 0.0
    unintended_contacts: set[tuple[str, str]] = field(default_factory=set)
    stopped: bool = False  # a guarded move ended early by its stop condition


def grip_geometry(env: Environment):
    """The mounted gripper's pad geometry (``grasping.GripGeometry``), measured once per environment."""
    from muble_plugins.primitives.grasping import measure_grip

    grip = env.cache.get("grip_geometry")
    if grip is None:
        # The pads' geometry depends on the gripper model alone: measured once per process for each kind.
        kind = (env.names.robot, type(env.names.gripper_format).__name__, tuple(env.names.left_pads),
                tuple(env.names.right_pads), float(env.model.opt.timestep))
        grip = _grips_by_kind.get(kind)
        if grip is None:
            grip = _grips_by_kind[kind] = measure_grip(env)
        env.cache["grip_geometry"] = grip
    return grip


def pad_gap(env) -> float:
    """Distance (m) between the inner faces of the finger pads as the fingers are now."""
    from muble_plugins.primitives.grasping import pad_faces

    left = [env.model.geom(n).id for n in env.names.left_pads]
    right = [env.model.geom(n).id for n in env.names.right_pads]
    return pad_faces(env.model, env.data, env.model.site(env.ee_site).id, left, right)[2]


def long_move_planner(env: Environment) -> MotionPlanner:
    """The planner for moves through free space: the run's (``env.planner``, the ``planner`` config group's
    choice); for an environment built outside a run, the ``ompl`` planner with its configured options."""
    if isinstance(env.planner, MotionPlanner):
        return env.planner
    return _built(env, "ompl")


def straight_line_planner(env: Environment) -> MotionPlanner:
    """The straight-line Cartesian planner of short moves (into a grasp, up, down), with the options of
    ``muble_conf/planner/straight_line.yaml``."""
    return _built(env, "straight_line")


def _built(env: Environment, name: str) -> MotionPlanner:
    # Built once per environment: creating one validates its options, which costs more than a short plan.
    key = f"planner:{name}"
    if key not in env.cache:
        from muble import get_registry
        from muble_conf import group_defaults

        env.cache[key] = get_registry().create("planner", name, group_defaults("planner", name))
    return env.cache[key]


def body_name(env, obj_id: int) -> str:
    try:
        return env.names.objects[int(obj_id)]
    except (KeyError, ValueError, TypeError):
        from muble.core.errors import unknown_name

        raise PlanningError(unknown_name("object id", str(obj_id), [str(i) for i in env.names.objects])) from None


def touching_bodies(env, bodies: set[int]) -> set[int]:
    """Bodies in contact (in the live physics) with any of ``bodies``."""
    m, d = env.model, env.data
    out = set()
    for c in d.contact[: d.ncon]:
        b1, b2 = m.geom_bodyid[c.geom[0]], m.geom_bodyid[c.geom[1]]
        if b1 in bodies and b2 not in bodies:
            out.add(int(b2))
        elif b2 in bodies and b1 not in bodies:
            out.add(int(b1))
    return out


def execute(env, trajectory: Trajectory, world: CollisionWorld, allowed: set[int] = frozenset(),
            settle: float = 0.2, stop=None) -> MotionReport:
    """Track ``trajectory`` and count, in physics, contacts of the arm or held object with anything else.

    ``allowed`` bodies (grasp target, support) may be touched. Contacts are read after every control sample.
    ``stop(env)``, where given, ends the motion early (a guarded move) when it returns True: the report's
    ``stopped`` says so, and the arm holds where it stopped (no settle).
    """
    m = env.model
    robot = world.robot_bodies
    held = {m.body(env.names.objects[env.held_object]).id} if env.held_object is not None else set()
    own = robot | held
    report = MotionReport()

    def watch(e) -> bool:
        d = e.data
        for c in d.contact[: d.ncon]:
            if c.dist > 0 or m.geom_contype[c.geom[0]] == CONTENTS_COLLISION_CLASS:
                continue  # loose contents meet only their own cavity's walls: inside one object, not a contact
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            if (b1 in own) == (b2 in own):
                continue
            other = b2 if b1 in own else b1
            mine = b1 if b1 in own else b2
            if other in allowed or (mine in held and other in robot):
                continue
            report.unintended_contacts.add((m.body(mine).name, m.body(other).name))
        return stop is not None and bool(stop(e))

    result = env.follow(trajectory, settle=settle, stop=watch)
    watch(env)
    report.duration, report.final_error = result.duration, result.final_error
    report.stopped = bool(result.stopped_early)
    if report.unintended_contacts:
        logger.info("unintended contacts while moving: %s", sorted(report.unintended_contacts))
    return report


def hover_pose(env, xy: np.ndarray, clear_z: float, quat: np.ndarray, height: float = HOVER) -> PoseGoal:
    """The hand ``height`` above ``clear_z`` over ``xy``, turned to ``quat``."""
    return PoseGoal(Pose(np.array([xy[0], xy[1], clear_z + height]), quat), *tol.FREE)

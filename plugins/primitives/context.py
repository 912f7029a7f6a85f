"""What every primitive needs from the environment: a collision world kept in sync, planners, trajectory
execution with contact counting, and the table's geometry.

The collision world is built once per environment (a model copy) and re-synced before every plan, so planning
never writes to the live simulation.
"""
from __future__ import annotations

import logging
import weakref
from dataclasses import dataclass, field

import mujoco
import numpy as np

from muble import MotionPlanner, PlanningError, Pose, PoseGoal, Trajectory
from muble.core.table import part_region as table_part_region
from muble.sim.collision_world import MujocoCollisionWorld

logger = logging.getLogger(__name__)

HOVER = 0.12  # m between an object's top and the hand when moving above it
TABLE_MARGIN = 0.08  # m kept free along the table's edges when choosing a place on it

_worlds: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_grips: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_grips_by_kind: dict[tuple, object] = {}


@dataclass
class MotionReport:
    """How a tracked motion went: duration, tracking error and unintended contacts seen in physics."""

    duration: float = 0.0
    final_error: float = 0.0
    unintended_contacts: set[tuple[str, str]] = field(default_factory=set)


def collision_world(env) -> MujocoCollisionWorld:
    """The environment's collision world, synced with its current state (held object included)."""
    world = _worlds.get(env)
    if world is None:
        world = MujocoCollisionWorld(env.model, env.data, env.arm_joint_names, env.ee_site, "robot0_base",
                                     env.names.hand_body)
        _worlds[env] = world
    world.hold(None)
    world.allow_contact([])
    world.sync(env.data)
    if env.held_object is not None:
        world.hold(env.names.objects[env.held_object])
    return world


def grip_geometry(env):
    """The mounted gripper's pad geometry (``grasping.GripGeometry``), measured once per environment."""
    from muble_plugins.primitives.grasping import measure_grip

    grip = _grips.get(env)
    if grip is None:
        # The pads' geometry depends on the gripper model alone: measured once per process for each kind.
        kind = (env.names.robot, type(env.names.gripper_format).__name__, tuple(env.names.left_pads),
                tuple(env.names.right_pads), float(env.model.opt.timestep))
        grip = _grips_by_kind.get(kind)
        if grip is None:
            grip = _grips_by_kind[kind] = measure_grip(env)
        _grips[env] = grip
    return grip


def pad_gap(env) -> float:
    """Distance (m) between the inner faces of the finger pads as the fingers are now."""
    from muble_plugins.primitives.grasping import pad_faces

    left = [env.model.geom(n).id for n in env.names.left_pads]
    right = [env.model.geom(n).id for n in env.names.right_pads]
    return pad_faces(env.model, env.data, env.model.site(env.ee_site).id, left, right)[2]


def planner(env, name: str) -> MotionPlanner:
    """The environment's configured planner for long moves (``env.planner``) or a built-in one by name."""
    configured = getattr(env, "planner", None)
    if name == "ompl" and isinstance(configured, MotionPlanner):
        return configured
    from muble import get_registry

    return get_registry().create("planner", name)


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


def execute(env, trajectory: Trajectory, world: MujocoCollisionWorld, allowed: set[int] = frozenset(),
            settle: float = 0.2) -> MotionReport:
    """Track ``trajectory`` and count, in physics, contacts of the arm or held object with anything else.

    ``allowed`` bodies (grasp target, support) may be touched. Contacts are read after every control sample.
    """
    m = env.model
    robot = world.robot_bodies
    held = {m.body(env.names.objects[env.held_object]).id} if env.held_object is not None else set()
    own = robot | held
    report = MotionReport()

    def watch(e) -> bool:
        d = e.data
        for c in d.contact[: d.ncon]:
            if c.dist > 0:
                continue
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            if (b1 in own) == (b2 in own):
                continue
            other = b2 if b1 in own else b1
            mine = b1 if b1 in own else b2
            if other in allowed or (mine in held and other in robot):
                continue
            report.unintended_contacts.add((m.body(mine).name, m.body(other).name))
        return False

    result = env.follow(trajectory, settle=settle, stop=watch)
    watch(env)
    report.duration, report.final_error = result.duration, result.final_error
    if report.unintended_contacts:
        logger.info("unintended contacts while moving: %s", sorted(report.unintended_contacts))
    return report


def plan_to(env, world: MujocoCollisionWorld, goal: PoseGoal, how: str = "ompl") -> Trajectory:
    return planner(env, how).plan(env.arm_q(), goal, world)


def top_down(env, yaw: float = 0.0) -> np.ndarray:
    """Grip-site orientation pointing straight down, turned by ``yaw`` about the vertical from the rest pose."""
    rest = world_rest_quat(env)
    turn = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, turn, rest)
    return out


def world_rest_quat(env) -> np.ndarray:
    """Grip-site orientation at the robot's rest posture (pointing down for every supported arm)."""
    world = collision_world(env)
    return world.ee_pose(env.names.init_qpos).quat


@dataclass
class Table:
    centre: np.ndarray  # (x, y) of the top's centre
    half: np.ndarray  # (hx, hy)
    top_z: float
    body: int

    def part_region(self, part: str) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) corners in x, y where a placed object's centre goes to lie in a named part of the table.

        The parts are those of ``muble.core.table`` (the one definition tasks and success checks use: seen from
        the front camera, "left" is -y, "front" the far half), kept ``TABLE_MARGIN`` inside this table's top.
        """
        (x0, x1), (y0, y1) = table_part_region(part)
        lo = np.maximum([x0, y0], self.centre - self.half + TABLE_MARGIN)
        hi = np.minimum([x1, y1], self.centre + self.half - TABLE_MARGIN)
        return lo, hi


def table(env) -> Table:
    m, d = env.model, env.data
    g = m.geom("table_collision").id
    pos = d.geom_xpos[g]
    size = m.geom_size[g]
    return Table(pos[:2].copy(), size[:2].copy(), float(pos[2] + size[2]), int(m.geom_bodyid[g]))


def object_top(env, obj_id: int) -> float:
    """Height of an object's highest point (world z) from its current collision geometry."""
    m, d = env.model, env.data
    b = m.body(env.names.objects[obj_id]).id
    tops = []
    for g in np.flatnonzero(m.geom_bodyid == b):
        if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0:
            continue
        tops.append(d.geom_xpos[g][2] + m.geom_rbound[g])
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = m.geom_dataid[g]
            start, n = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
            verts = m.mesh_vert[start : start + n] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
            tops[-1] = float(verts[:, 2].max())
    return float(max(tops)) if tops else float(d.xpos[b][2])


def hover_pose(env, xy: np.ndarray, clear_z: float, quat: np.ndarray) -> PoseGoal:
    return PoseGoal(Pose(np.array([xy[0], xy[1], clear_z + HOVER]), quat), 0.005, 0.05)

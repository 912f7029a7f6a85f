"""Putting a held object down: free places on the table from the objects' real footprints, and descents onto a
place that are checked (reachable, continuous, collision-free) before anything moves.

A footprint is the convex hull, seen from above, of a body's collision geometry in its current pose. Which
centres are free is decided by the one rule of ``muble.stage.free_place`` (the held object's footprint, grown by
the gap, must not meet another's), which the symbolic world applies to the scene graph's bounding boxes.
"""
from __future__ import annotations

import logging

import mujoco
import numpy as np

from muble import PlanningError, Pose, PoseGoal, Trajectory
from muble.core import streams
from muble.stage import free_place
from muble.stage.free_place import DISC, PLACE_GAP, PLACE_SPACING
from muble.stage.geometry import geom_world_vertices, hull_2d, yaw_quat
from muble.stage.rest import resting_height
from muble_plugins.primitives import context as ctx
from muble_plugins.primitives import tolerances as tol
from muble_plugins.primitives.common import PART_OPEN, release_command

logger = logging.getLogger(__name__)

CANDIDATE_SPACING = 0.04  # m between the places a primitive tries in turn (neighbours fail alike)
MAX_CANDIDATES = 20
DESCENT_SEEDS = 6  # random arm configurations tried for a place the current arm cannot descend to
RISE = 0.04  # m risen straight up to leave what the arm or held object touches at the start of a move
CLEAR_RISE = 0.12  # m risen in such steps at most (the hover height over an object), still in contact or not


def held_depth(env) -> float:
    """How far the held object hangs below the grip site (0 when nothing is held)."""
    if env.held_object is None:
        return 0.0
    m = env.model
    b = m.body(env.names.objects[env.held_object]).id
    lowest = min(geom_bottom(env, g) for g in np.flatnonzero(m.geom_bodyid == b)
                 if m.geom_contype[g] or m.geom_conaffinity[g])
    return float(env.ee_pose().pos[2] - lowest)


def held_offset(env) -> np.ndarray:
    """Horizontal offset (x, y) of the held object's centre from the grip site: fixed while it is held,
    since the hand keeps its orientation when carrying and lowering."""
    return env.object_pose(env.held_object).pos[:2] - env.ee_pose().pos[:2]


def geom_heights(env, g: int) -> tuple[float, float]:
    """World z of geom ``g``'s lowest and highest points (a mesh's vertices, else its bounding sphere's)."""
    m, d = env.model, env.data
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        z = geom_world_vertices(m, d, g)[:, 2]
        return float(z.min()), float(z.max())
    return float(d.geom_xpos[g][2] - m.geom_rbound[g]), float(d.geom_xpos[g][2] + m.geom_rbound[g])


def geom_bottom(env, g: int) -> float:
    """World z of geom ``g``'s lowest point."""
    return geom_heights(env, g)[0]


def geom_top(env, g: int) -> float:
    """World z of geom ``g``'s highest point."""
    return geom_heights(env, g)[1]


def clear_top(env, xy: np.ndarray, table_top: float, skip: int | None) -> float:
    """The height to clear around ``xy``: the table top or whatever stands within 15 cm of it."""
    near = [env.object_top(i) for i in env.names.objects if i != skip
            and np.linalg.norm(env.object_pose(i).pos[:2] - xy) < 0.15]
    return max([table_top] + near)


def turned(env, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """(held object's horizontal offset from the grip site, grip-site orientation) once the hand has turned by
    ``yaw`` about the vertical, the object turning with it."""
    c, s = np.cos(yaw), np.sin(yaw)
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, yaw_quat(yaw), env.ee_pose().quat)
    return np.array([[c, -s], [s, c]]) @ held_offset(env), quat


def place_pose(env, xy: np.ndarray, support_top: float, gap: float, yaw: float = 0.0) -> Pose:
    """Grip-site pose that puts the held object's centre over ``xy``, its bottom ``gap`` above ``support_top``
    (the hand keeps the orientation it carries the object with, or turns by ``yaw`` about the vertical)."""
    offset, quat = turned(env, yaw)
    hand = np.asarray(xy, dtype=float) - offset
    return Pose(np.array([hand[0], hand[1], support_top + held_depth(env) + gap]), quat)


def resting_top(env, target: int, held: int, yaw: float = 0.0) -> float:
    """Height the held object's bottom comes to rest at on ``target`` (scene ids), its centre over the target's and
    turned with the hand by ``yaw`` about the vertical: where it first touches the target's collision geometry as it
    is lowered straight down (``first_touch``: the inner floor of a bowl a can fits into, the rim of one a wider
    object spans, a bowl's wall under a mug's handle, which stands above the mug's base). Where lowering never
    meets the target, the highest point of the target under the held object's footprint (rays straight down), else
    the target's top."""
    m, d = env.model, env.data
    target_body = m.body(env.names.objects[target]).id
    held_body = m.body(env.names.objects[held]).id
    centre = env.object_pose(held).pos
    touch = first_touch(env, held_body, target_body, env.object_pose(target).pos[:2] - centre[:2], centre, yaw)
    if touch is not None:
        return touch
    top = env.object_top(target)
    shape = footprint(env, held_body) - d.xpos[held_body][:2]
    points = np.vstack([np.zeros((1, 2)), shape, 0.5 * shape]) + env.object_pose(target).pos[:2]
    groups = np.zeros(6, dtype=np.uint8)
    groups[3] = 1  # object collision geoms
    height = resting_height(m, d, target_body, points, top + 0.05, held_body, groups)
    return top if height is None else height


# m between the lowered object and its support at which it counts as touching: the search for the first contact
# stops there (a release gap of ``RELEASE_GAPS`` is added to what it finds).
TOUCH = 0.0005
TOUCH_STEPS = 100  # steps down at most; stopping early leaves the object above the contact, never in it
TOUCH_START = 0.01  # m above the support's top that the lowered object's bottom starts from


def collision_geoms(m, body: int) -> list[int]:
    return [int(g) for g in np.flatnonzero(m.geom_bodyid == body) if m.geom_contype[g] or m.geom_conaffinity[g]]


def first_touch(env, body: int, support: int, shift: np.ndarray, centre: np.ndarray, yaw: float = 0.0) -> float | None:
    """World z of ``body``'s bottom where, moved by ``shift`` (x, y) and turned by ``yaw`` about the vertical
    through ``centre``, then lowered straight down from ``TOUCH_START`` above ``support``'s top, it first comes
    within ``TOUCH`` of ``support``'s collision geometry; ``None`` where it passes the support's bottom without
    touching it.

    Each step goes down by the smallest distance between the two bodies' convex parts (MuJoCo's
    ``mj_geomDistance``, on a scratch copy of the poses: the simulation is not touched); a vertical move no longer
    than the distance cannot reach the support, so the search never passes a contact, whatever the shapes. The
    object's own shape counts, not only its outline: a mug's handle stands above its base, and over a bowl it meets
    the wall well below the rim."""
    m, d = env.model, env.data
    mine, theirs = collision_geoms(m, body), collision_geoms(m, support)
    if not mine or not theirs:
        return None
    scratch = mujoco.MjData(m)
    scratch.geom_xpos[theirs] = d.geom_xpos[theirs]
    scratch.geom_xmat[theirs] = d.geom_xmat[theirs]
    c, s = np.cos(yaw), np.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    placed = {g: turn @ (d.geom_xpos[g] - centre) + centre + [shift[0], shift[1], 0.0] for g in mine}
    for g in mine:
        scratch.geom_xmat[g] = (turn @ d.geom_xmat[g].reshape(3, 3)).ravel()
    bottom = min(geom_bottom(env, g) for g in mine)  # turning about the vertical keeps it
    floor = min(geom_bottom(env, g) for g in theirs)
    dz = max(geom_top(env, g) for g in theirs) + TOUCH_START - bottom
    radius = m.geom_rbound
    for _ in range(TOUCH_STEPS):
        for g in mine:
            scratch.geom_xpos[g] = placed[g] + [0.0, 0.0, dz]
        gap = np.inf
        for a in mine:
            for b in theirs:
                far = np.linalg.norm(scratch.geom_xpos[a] - scratch.geom_xpos[b]) - radius[a] - radius[b]
                if far < gap:  # bounding spheres closer than the nearest pair so far
                    gap = min(gap, mujoco.mj_geomDistance(m, scratch, a, b, 1.0, None))
        if gap <= TOUCH:
            return float(bottom + dz)
        if bottom + dz < floor:
            return None
        dz -= gap
    return float(bottom + dz)


def footprint(env, body: int) -> np.ndarray:
    """World (x, y) points whose convex hull is the body's collision geometry seen from above."""
    m, d = env.model, env.data
    points = []
    for g in np.flatnonzero(m.geom_bodyid == body):
        if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0:
            continue
        rot, pos = d.geom_xmat[g].reshape(3, 3), d.geom_xpos[g]
        kind = m.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_MESH:
            points.append(geom_world_vertices(m, d, g)[:, :2])
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * m.geom_size[g]
            points.append((corners @ rot.T + pos)[:, :2])
        else:  # round shapes: their bounding circle
            points.append(pos[:2] + m.geom_rbound[g] * DISC)
    if not points:
        return d.xpos[body][:2][None].copy()
    return hull_2d(np.vstack(points))


def obstacles(env, held: int) -> list[np.ndarray]:
    """The footprints of every object but ``held``."""
    m = env.model
    return [footprint(env, m.body(name).id) for i, name in env.names.objects.items() if i != held]


def held_outline(env, held: int) -> np.ndarray:
    """The held object's footprint relative to its centre, as it is turned now."""
    body = env.model.body(env.names.objects[held]).id
    return footprint(env, body) - env.data.xpos[body][:2]


def free_places(env, lo: np.ndarray, hi: np.ndarray, held: int, prefer: np.ndarray | None = None,
                gap: float = PLACE_GAP, spacing: float = PLACE_SPACING, yaw: float = 0.0) -> list[np.ndarray]:
    """Centres in the box ``lo``-``hi`` where the held object, as it is turned now and then by ``yaw`` about the
    vertical, keeps ``gap`` from every other object's footprint; nearest ``prefer`` (default: the box's centre)
    first (the rule of ``muble.stage.free_place``, on the bodies' collision geometry)."""
    return free_place.free_places(lo, hi, held_outline(env, held), obstacles(env, held), prefer, gap, spacing, yaw)


def no_room(part: str, held: int) -> str:
    """The failure of a put-down on a table part with no free place, in both worlds."""
    return f"no free space on the {part} part of the table for object {held}; choose another part"


def is_free(env, xy: np.ndarray, held: int, gap: float = PLACE_GAP) -> bool:
    return bool(free_place.free_mask(np.asarray(xy, dtype=float)[None], held_outline(env, held),
                                     obstacles(env, held), gap)[0])


def spread(places: list[np.ndarray], spacing: float = CANDIDATE_SPACING, limit: int = MAX_CANDIDATES):
    """The first places in order, each ``spacing`` or more from those already taken."""
    out: list[np.ndarray] = []
    for p in places:
        if all(np.linalg.norm(p - q) >= spacing for q in out):
            out.append(p)
            if len(out) == limit:
                break
    return out


def _reversed(path: Trajectory) -> Trajectory:
    return Trajectory(path.q[::-1].copy(), path.t[-1] - path.t[::-1], path.joint_names)


def plan_descent(env, world, place: Pose, above: np.ndarray, support: int,
                 gripper_may_touch: bool = True) -> tuple[np.ndarray, Trajectory]:
    """An arm configuration with the hand at ``above`` (collision-free) and the straight descent from it to
    ``place`` (touching only ``support``): the arm's current branch first, then configurations found from the
    place upwards, which avoid a singularity or joint limit met on the way down.

    Without ``gripper_may_touch`` only the held object may touch the support, the fingers keep the planning
    clearance from it: an object set down into a bowl, with the fingers pressed on the bowl's walls, could not
    be let go (the opening fingers wedge against the walls and lift the bowl as they rise).

    Raises ``PlanningError`` with the first reason when the place is out of reach or every descent is blocked.
    """
    line = ctx.straight_line_planner(env)
    above_goal = PoseGoal(Pose(np.asarray(above, dtype=float), place.quat), *tol.FREE)
    place_goal = PoseGoal(place, *tol.CONTACT)
    lim = world.joint_limits
    seeds = [env.arm_q(), *streams.legacy_stream(streams.PLACE_DESCENT, 7).uniform(lim[:, 0], lim[:, 1],
                                                                              size=(DESCENT_SEEDS, len(lim)))]
    reasons: list[str] = []
    try:
        world.allow_contact([])
        q_above = world.inverse_kinematics(above_goal, seeds=seeds[0][None])
        world.allow_contact([support], held_only=not gripper_may_touch)
        return q_above, line.plan(q_above, place_goal, world)
    except PlanningError as e:
        reasons.append(str(e))
        if "out of reach" in str(e):
            raise
    finally:
        world.allow_contact([])
    for seed in seeds:
        try:
            world.allow_contact([support], held_only=not gripper_may_touch)
            q_place = world.local_inverse_kinematics(place_goal, seed)
            up = line.plan(q_place, above_goal, world)
            world.allow_contact([])
            if not world.is_valid(up.q[-1]):
                raise PlanningError(f"the pose above the place is in collision {world.last_contacts[:2]}")
            world.allow_contact([support], held_only=not gripper_may_touch)
            try:
                return up.q[-1], line.plan(up.q[-1], place_goal, world)
            except PlanningError:
                return up.q[-1], _reversed(up)  # the same line, checked on the way up
        except PlanningError as e:
            reasons.append(str(e))
        finally:
            world.allow_contact([])
    raise PlanningError(reasons[0])


def clear_start(env, world) -> ctx.MotionReport | None:
    """Where the arm or the held object starts in contact (a held object still touching what it stood on,
    fingers beside the object just let go), an empty closed hand first opens, then the hand rises straight up
    by ``RISE`` touching only that, again while the arm is still in contact, up to ``CLEAR_RISE`` in all (a
    finger left down between nested bowls is deeper than one step); ``None`` when the start is clear. The caller
    re-syncs its collision world afterwards."""
    world.allow_contact([])
    if world.is_valid(env.arm_q()):
        return None
    if env.held_object is None and env.gripper_command > PART_OPEN:
        # A grasp that did not take (the fingers closed on a mug's handle, or on a glass without holding it)
        # leaves the hand closed round the object, and rising would lift it along: the hand lets go first, as
        # ``lower`` does (part way round a thin part, else fully).
        logger.info("starting in contact with the hand closed and nothing held: opening it first")
        env.set_gripper(release_command(env))
        env.hold(tol.SETTLE)
        world = env.collision_world()
        world.allow_contact([])
        if world.is_valid(env.arm_q()):
            return None
    m = env.model
    own = set(world.robot_bodies)
    if env.held_object is not None:
        own.add(m.body(env.names.objects[env.held_object]).id)
    report = None
    for _ in range(int(round(CLEAR_RISE / RISE))):
        touched = {m.body(name).id for pair in world.last_contacts for name in pair} - own
        if not touched:
            # Only the arm itself: links a hair inside their clearance (a tracked move's error) are a start the
            # planners may leave (``resting_at``); links touching are not.
            with world.resting_at(env.arm_q()) as valid:
                if valid:
                    return report
            raise PlanningError(f"start configuration is in collision {world.last_contacts[:3]} (self-collision)")
        world.allow_contact(touched)
        pose = env.ee_pose()
        rise = PoseGoal(Pose(pose.pos + [0.0, 0.0, RISE], pose.quat), *tol.FREE)
        trajectory = ctx.straight_line_planner(env).plan(env.arm_q(), rise, world)
        logger.info("starting in contact with %s: rising %.0f cm first", sorted(touched), RISE * 100)
        report = merge(report, ctx.execute(env, trajectory, world, allowed=touched))
        world = env.collision_world()
        world.allow_contact([])
        if world.is_valid(env.arm_q()):
            break
    return report


def merge(*reports: ctx.MotionReport | None) -> ctx.MotionReport:
    out = ctx.MotionReport()
    for r in reports:
        if r is None:
            continue
        out.duration += r.duration
        out.final_error = r.final_error
        out.unintended_contacts |= r.unintended_contacts
    return out

"""Grasp and placement poses: from an object's grasp frames (object coordinates) to world poses of the hand,
and free places on the table for putting an object down.

A grasp frame says where the middle of the finger pads goes and how the hand is turned (x: the fingers' closing
direction, z: the approach, from the hand into the object). ``GripGeometry`` measures, for the gripper actually
mounted, where its pads sit relative to its grip site and which way they close, so one frame serves every
gripper: a Panda's short pads just behind the site, a Robotiq's long pads that swing forwards as they close.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from muble import Pose
from muble.stage.geometry import mesh_vertices, mujoco_quat_matrix, yaw_quat

TABLE_CLEARANCE = 0.004  # m the lowest fingertip stays above the table top in a grasp pose
PRE_GRASP = 0.10  # m back along the approach from the grasp pose where the straight move in starts
PAD_MARGIN = 0.002  # m free on each side of an object between the open pads
SQUEEZE_MARGIN = 0.001  # m by which the closed pads must be narrower than what they are to hold
FINGER_TRAVEL = 0.8  # s of simulated time for the fingers to open or close fully when measuring them
SWEEP_STEP = np.radians(6.0)  # rad between grasps swept about an object's vertical axis
CLEAR_ENOUGH = 0.02  # m between the open hand and a neighbour beyond which a grasp is not ranked lower
TOUCHING = 0.002  # m: an open hand closer than this to a neighbour at the grasp pose cannot be used there
CROWDED = 10.0  # rank penalty putting such grasps after every other


def _mat_quat(mat: np.ndarray) -> np.ndarray:
    out = np.empty(4)
    mujoco.mju_mat2Quat(out, np.ascontiguousarray(mat).ravel())
    return out


@dataclass
class GripGeometry:
    """Where a gripper's pads are, in its grip-site frame, with the fingers open and closed.

    ``closing`` and ``approach`` are unit axes in the site frame; ``open_centre``/``closed_centre`` the midpoint
    of the two pads; ``open_gap``/``closed_gap`` the distance between the pads' inner faces; ``tip_depth`` how
    far the fingers reach beyond the pad midpoint along the approach (open).
    """

    closing: np.ndarray
    approach: np.ndarray
    open_centre: np.ndarray
    closed_centre: np.ndarray
    open_gap: float
    closed_gap: float
    tip_depth: float

    @property
    def max_width(self) -> float:
        """Widest object the open pads close on with ``PAD_MARGIN`` to spare on each side."""
        return self.open_gap - 2 * PAD_MARGIN

    def centre(self, width: float) -> np.ndarray:
        """Pad midpoint (site frame) when the pads have closed to ``width``: linkage grippers move it along the
        approach as they close; between the measured ends it is interpolated."""
        span = self.open_gap - self.closed_gap
        s = 0.0 if span <= 1e-6 else float(np.clip((self.open_gap - width) / span, 0.0, 1.0))
        return (1 - s) * self.open_centre + s * self.closed_centre

    def site_pose(self, frame: Pose, width: float) -> Pose:
        """Grip-site pose that puts the pads' midpoint on ``frame`` with the fingers closing along its x axis and
        the hand approaching along its z axis."""
        site_rot = mujoco_quat_matrix(frame.quat) @ self._frame_in_site().T
        return Pose(frame.pos - site_rot @ self.centre(width), _mat_quat(site_rot))

    def _frame_in_site(self) -> np.ndarray:
        """A grasp frame's axes in site coordinates (a function of the gripper alone, computed once)."""
        cached = self.__dict__.get("_in_site")
        if cached is None:
            x = self.closing
            z = self.approach - (self.approach @ x) * x
            z /= np.linalg.norm(z)
            cached = self.__dict__["_in_site"] = np.column_stack([x, np.cross(z, x), z])
        return cached


def pad_faces(m, d, site: int, left: list[int], right: list[int]) -> tuple[np.ndarray, np.ndarray, float]:
    """(closing axis, pad midpoint, gap between inner faces), site frame, from the finger pad geoms."""
    rot, origin = d.site_xmat[site].reshape(3, 3), d.site_xpos[site]
    centres = [np.mean([rot.T @ (d.geom_xpos[g] - origin) for g in pads], axis=0) for pads in (left, right)]
    axis = centres[1] - centres[0]
    axis /= np.linalg.norm(axis)

    def half(g):  # half extent of a pad along the closing axis
        geom_rot = rot.T @ d.geom_xmat[g].reshape(3, 3)
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            return float(np.abs(axis @ geom_rot) @ m.geom_size[g])
        return float(m.geom_size[g][0])

    gap = float(axis @ (centres[1] - centres[0])) - half(left[0]) - half(right[0])
    return axis, 0.5 * (centres[0] + centres[1]), gap


def measure_grip(env) -> GripGeometry:
    """The pad geometry of ``env``'s gripper, from its own model: the fingers are opened and closed in a copy
    in which nothing but the gripper collides (the live simulation is not touched).

    The copy starts from the model's rest state with the arm at its rest configuration, not from the live state:
    the geometry is then a function of the robot and gripper alone, whatever the environment was doing when it
    was first asked for (it is cached per process, so it must not depend on which episode came first)."""
    m = copy.deepcopy(env.model)
    d = mujoco.MjData(m)
    rest = np.asarray(env.names.init_qpos, dtype=float)
    for name, q in zip(env.names.arm_joints, rest):
        d.qpos[m.joint(name).qposadr[0]] = q
    m.opt.gravity[:] = 0.0
    hand = m.body(env.names.hand_body).id
    in_gripper = np.array([below(m, b, hand) for b in range(m.nbody)])
    outside = ~in_gripper[m.geom_bodyid]
    m.geom_contype[outside] = 0
    m.geom_conaffinity[outside] = 0
    site = m.site(env.ee_site).id
    left = [m.geom(n).id for n in env.names.left_pads]
    right = [m.geom(n).id for n in env.names.right_pads]
    ctrl_ids = env.gripper_actuator_ids
    states = {}
    for name, ctrl in (("open", env.gripper_open_ctrl), ("closed", env.gripper_closed_ctrl)):
        d.ctrl[ctrl_ids] = ctrl
        env.set_arm_target(rest, data=d)
        for _ in range(int(FINGER_TRAVEL / m.opt.timestep)):
            mujoco.mj_step(m, d)
        mujoco.mj_forward(m, d)
        states[name] = pad_faces(m, d, site, left, right)
    closing, open_centre, open_gap = states["open"]
    _, closed_centre, closed_gap = states["closed"]
    approach = np.array([0.0, 0.0, 1.0])  # robosuite grip sites point out of the hand along z
    approach = approach - (approach @ closing) * closing
    approach /= np.linalg.norm(approach)
    tip = max(_reach(m, d, site, g, approach) for g in np.flatnonzero(in_gripper[m.geom_bodyid])
              if m.geom_contype[g] or m.geom_conaffinity[g]) - float(open_centre @ approach)
    return GripGeometry(closing, approach, open_centre, closed_centre, open_gap, closed_gap, max(tip, 0.0))


def below(m, body: int, root: int) -> bool:
    while body not in (root, 0):
        body = int(m.body_parentid[body])
    return body == root


def _reach(m, d, site: int, g: int, axis: np.ndarray) -> float:
    """Farthest point of geom ``g`` along ``axis`` (site frame) from the site."""
    rot, origin = d.site_xmat[site].reshape(3, 3), d.site_xpos[site]
    centre = rot.T @ (d.geom_xpos[g] - origin)
    geom_rot = rot.T @ d.geom_xmat[g].reshape(3, 3)
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        return float((mesh_vertices(m, g) @ geom_rot.T @ axis).max() + centre @ axis)
    if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
        return float(centre @ axis + np.abs(axis @ geom_rot) @ m.geom_size[g])
    return float(centre @ axis + m.geom_rbound[g])


def _compose(pose_pos, pose_quat, pos, quat) -> tuple[np.ndarray, np.ndarray]:
    out = np.empty(4)
    mujoco.mju_mulQuat(out, pose_quat, np.asarray(quat, dtype=float))
    return pose_pos + mujoco_quat_matrix(pose_quat) @ np.asarray(pos, dtype=float), out


def _turned(quat: np.ndarray, angle: float) -> np.ndarray:
    """``quat`` turned by ``angle`` about its own z axis (the approach direction)."""
    out = np.empty(4)
    mujoco.mju_mulQuat(out, quat, yaw_quat(angle))
    return out


def _axis(quat: np.ndarray, k: int) -> np.ndarray:
    return mujoco_quat_matrix(quat)[:, k]


def grasp_approach(grasp: Pose) -> np.ndarray:
    """Unit vector along which the hand moves into the grasp (the grip site's z axis)."""
    return _axis(grasp.quat, 2)


def grasp_candidates(object_pose: Pose, model, table_top: float, max_width: float | None = None,
                     rest_quat: np.ndarray | None = None, grip: GripGeometry | None = None,
                     clearance=None, limit: int | None = None) -> list[Pose]:
    """World grip-site poses for grasping, best first.

    A grasp frame (object coordinates) places the pads' midpoint, x along the fingers' closing direction and z
    along the approach; ``grip`` maps it to the grip site of the mounted gripper (without one the frame is
    taken as the site itself). Frames wider than the open fingers (``max_width``, by default the gripper's)
    or thinner than the closed ones are left out. Every frame is tried as given and turned half a turn about its approach axis (the fingers are
    symmetric, the wrist's limits are not); boxes, and cylinders gripped about their axis, also get the quarter
    turns, since those grasps work from any side. Top-down grasps come first, then those whose closing direction
    is nearest the hand's at ``rest_quat`` (less wrist travel).

    With ``clearance`` (a grip-site pose -> metres, e.g. ``hand_clearance``), frames that hold the same way from
    any direction around the object (rim pinches within their flat wall piece, grasps about the object's axis)
    are also tried swept about the vertical axis in ``SWEEP_STEP`` steps, so that the hand can face away from a
    neighbour; candidates whose open hand comes closer than ``CLEAR_ENOUGH`` to anything but the target are
    ranked lower in proportion, and those where it already touches something go last.

    ``limit``: only the first ``limit`` candidates of that ranking are wanted (the same ones, in the same order).
    Clearance is then measured best base rank first, and no further once no candidate left can enter them: it
    only ever adds to a rank.
    """
    if max_width is None:
        max_width = grip.max_width if grip is not None else np.inf
    # A part thinner than the closed pads' gap (a thin rim for a gripper that cannot close fully) is never held.
    min_width = grip.closed_gap + SQUEEZE_MARGIN if grip is not None else 0.0
    rest_x = None
    if rest_quat is not None:
        rest_x = mujoco_quat_matrix(rest_quat) @ (grip.closing if grip is not None else np.array([1.0, 0.0, 0.0]))
    tip = grip.tip_depth if grip is not None else 0.0
    drafts = []  # (rank without clearance, order made, grasp frame pose, width held, sweep)
    pose_rot = mujoco_quat_matrix(object_pose.quat)  # the object's rotation, for every frame (``_compose``'s)
    for index, (frame, (on_axis, swept)) in enumerate(zip(model.grasp_frames,
                                                          _frame_sweeps(model, clearance is not None))):
        if not min_width <= frame.width <= max_width:
            continue
        for sweep, stretch, position, frame_quat in swept:
            # ``_compose(object_pose.pos, object_pose.quat, position, frame_quat)``, the rotation worked out once
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, object_pose.quat, frame_quat)
            pos = object_pose.pos + pose_rot @ position
            yaws = [0.0, np.pi]
            if model.grasp_type == "box" or (model.grasp_type == "cylinder" and on_axis):
                yaws += [np.pi / 2, -np.pi / 2]
            for yaw in yaws:
                q = _turned(quat, yaw)
                axes = mujoco_quat_matrix(q)
                approach, closing = axes[:, 2], axes[:, 0]
                # The fingertips reach past the pads along the approach; they must stay off the table top.
                p = pos.copy()
                p[2] = max(p[2], table_top + TABLE_CLEARANCE + tip * max(0.0, -approach[2]))
                down = -approach[2]  # np.clip(down, -1.0, 1.0) without its per-call overhead (NaN kept too)
                tilt = float(np.arccos(1.0 if down > 1.0 else -1.0 if down < -1.0 else down))
                turn = float(np.arccos(min(1.0, abs(float(closing @ rest_x))))) if rest_x is not None else 0.0
                score = tilt + 0.3 * turn + 0.002 * index + 0.001 * abs(sweep)
                # Ties keep the order of generation (which is the order among those kept).
                drafts.append((score, len(drafts), Pose(p, q), frame.width * stretch, sweep))

    def site_of(draft) -> Pose:
        return grip.site_pose(draft[2], draft[3]) if grip is not None else draft[2]

    if clearance is None:
        drafts.sort(key=lambda item: item[:2])
        return [site_of(d) for d in drafts[:limit]]
    scored = []
    order = sorted(drafts, key=lambda item: item[:2]) if limit is not None else drafts
    for draft in order:
        if limit is not None and len(scored) >= limit:
            scored.sort(key=lambda item: item[:2])
            del scored[limit:]
            if scored[-1][:2] < draft[:2]:
                break  # every candidate left ranks after the last one wanted
        score, rank, _, _, sweep = draft
        site = site_of(draft)
        free = clearance(site)
        if sweep != 0.0 and free < TOUCHING:
            continue  # an extra that cannot be used here
        score += CROWDED if free < TOUCHING else max(0.0, CLEAR_ENOUGH - free) / CLEAR_ENOUGH
        scored.append((score, rank, site))
    scored.sort(key=lambda item: item[:2])
    return [pose for *_, pose in scored[:limit]]


# ``_frame_sweeps``'s rows by the object's grasp type and frames (their numbers): the same for every scene the
# object is in.
_frame_sweep_rows: dict[tuple, list] = {}


def _frame_sweeps(model, swept: bool) -> list[tuple]:
    """Per grasp frame of ``model``, in order: (on the object's axis, [(sweep angle, radial stretch,
    position, orientation) of each copy of it (``_sweeps``, ``_swept``); the frame alone unless ``swept``]).
    A function of the object's grasp type and frames alone, worked out once for each."""
    key = (model.grasp_type, swept, tuple((np.asarray(f.position, dtype=float).tobytes(),
                                           np.asarray(f.quat, dtype=float).tobytes(), float(f.width))
                                          for f in model.grasp_frames))
    rows = _frame_sweep_rows.get(key)
    if rows is None:
        rows = []
        for frame in model.grasp_frames:
            on_axis = float(np.hypot(frame.position[0], frame.position[1])) < 1e-3
            sweeps = _sweeps(frame, model.grasp_frames, on_axis, model.grasp_type) if swept else [(0.0, 1.0)]
            copies = []
            for sweep, stretch in sweeps:
                position, frame_quat = _swept(frame, sweep, stretch)
                position, frame_quat = position.copy(), frame_quat.copy()  # not the frame's own arrays
                position.flags.writeable = frame_quat.flags.writeable = False
                copies.append((sweep, stretch, position, frame_quat))
            rows.append((on_axis, copies))
        _frame_sweep_rows[key] = rows
    return rows


def _sweeps(frame, frames, on_axis: bool, grasp_type: str) -> list[tuple[float, float]]:
    """(angle about the object's vertical axis, radial stretch) for the swept copies of a frame.

    A frame on the axis turns freely (the body is round): a third of the way to the next of the 45-degree set
    either side. A rim pinch (off the axis, closing radially) slides along its flat wall piece, short of the
    corners: the pads close across the same wall, now slanted by the sweep angle, so the frame moves out to the
    wall's middle there (1 / cos). Other frames (a handle, a box) hold one place only.
    """
    if grasp_type == "box":
        return [(0.0, 1.0)]
    if on_axis:
        return [(a, 1.0) for a in (0.0, -np.pi / 12, np.pi / 12)]
    radial = np.array([frame.position[0], frame.position[1], 0.0])
    closing = mujoco_quat_matrix(frame.quat)[:, 0].copy()
    closing[2] = 0.0
    size = np.linalg.norm(closing) * np.linalg.norm(radial)
    if size < 1e-9 or abs(closing @ radial) < 0.99 * size:
        return [(0.0, 1.0)]
    half = 0.5 * _piece_angle(frame, frames)
    steps = int(np.floor(0.75 * half / SWEEP_STEP))
    return [(k * SWEEP_STEP, 1.0 / np.cos(k * SWEEP_STEP)) for k in (0, *range(-steps, 0), *range(1, steps + 1))]


def _piece_angle(frame, frames) -> float:
    """Angle between a rim pinch and its nearest sibling on the same rim (one wall piece of the rim)."""
    r0, z0 = np.hypot(*frame.position[:2]), frame.position[2]
    a0 = np.arctan2(frame.position[1], frame.position[0])
    gaps = [abs(np.remainder(np.arctan2(f.position[1], f.position[0]) - a0 + np.pi, 2 * np.pi) - np.pi)
            for f in frames if f is not frame and abs(np.hypot(*f.position[:2]) - r0) < 0.002
            and abs(f.position[2] - z0) < 0.002]
    gaps = [g for g in gaps if g > 1e-3]
    return float(min(gaps)) if gaps else np.pi / 5


def _swept(frame, angle: float, stretch: float) -> tuple[np.ndarray, np.ndarray]:
    """A frame's position and orientation turned by ``angle`` about the object's vertical axis, its radial
    distance scaled by ``stretch``."""
    pos = np.asarray(frame.position, dtype=float)
    if angle == 0.0 and stretch == 1.0:
        return pos, np.asarray(frame.quat, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    pos = np.array([stretch * (c * pos[0] - s * pos[1]), stretch * (s * pos[0] + c * pos[1]), pos[2]])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, yaw_quat(angle), np.asarray(frame.quat, dtype=float))
    return pos, out


def hand_clearance(world, target_body: int | str, ignore=(), reach: float = CLEAR_ENOUGH):
    """A function of a grip-site pose: the smallest distance (capped at ``reach``) between the gripper as it is
    now (fingers open) placed at that pose and any collidable body but ``target_body``, the ``ignore`` bodies
    (the table: ``TABLE_CLEARANCE`` already keeps the fingers off it) and the robot, from the collision world's
    model. The arm is left out: this ranks grasps cheaply before any inverse kinematics.
    """
    m = world.model
    skip = {m.body(b).id if isinstance(b, str) else int(b) for b in (target_body, *ignore)}
    # The world's scratch data (a new MjData costs milliseconds), in the state a new one would reach here: every
    # pose read below is the kinematics' of this qpos (and of the mocap bodies, which nothing moves in it).
    user = object()
    d, _ = world.scratch_data(user)
    d.qpos[:] = world.data.qpos
    qpos = d.qpos.copy()
    mujoco.mj_kinematics(m, d)
    site = world.kinematics.site_id
    site_rot, site_pos = d.site_xmat[site].reshape(3, 3).copy(), d.site_xpos[site].copy()
    collidable = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
    hand = np.flatnonzero(collidable & np.isin(m.geom_bodyid, list(world.gripper_bodies)))
    others = np.flatnonzero(collidable & ~np.isin(m.geom_bodyid, list(world.robot_bodies | skip)))
    rel_pos = np.array([site_rot.T @ (d.geom_xpos[g] - site_pos) for g in hand]).reshape(-1, 3)
    rel_rot = [site_rot.T @ d.geom_xmat[g].reshape(3, 3) for g in hand]
    other_pos = d.geom_xpos[others].copy()
    other_r = m.geom_rbound[others]
    plane = other_r == 0
    hand_r = m.geom_rbound[hand]

    def clearance(pose: Pose) -> float:
        if not world.scratch_data(user)[1]:  # used by another since: its poses again (the hand's are set below)
            d.qpos[:] = qpos
            mujoco.mj_kinematics(m, d)
        rot = mujoco_quat_matrix(pose.quat)
        best = reach
        centres = pose.pos + rel_pos @ rot.T
        # Bounding spheres first (all hand geoms at once); a zero bound (a plane) is always measured.
        gaps = np.linalg.norm(other_pos[None] - centres[:, None], axis=2) - other_r[None] - hand_r[:, None]
        for k in np.flatnonzero(np.any(plane[None] | (gaps < best), axis=1)):
            near = plane | (gaps[k] < best)
            if not near.any():
                continue
            g = hand[k]
            d.geom_xpos[g] = centres[k]
            d.geom_xmat[g] = (rot @ rel_rot[k]).ravel()
            for o in others[near]:
                best = min(best, mujoco.mj_geomDistance(m, d, int(g), int(o), best, None))
        return float(best)

    return clearance

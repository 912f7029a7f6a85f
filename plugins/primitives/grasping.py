"""Grasp and placement poses: from an object's grasp frames (object coordinates) to world poses of the hand,
and free places on the table for putting an object down.
"""
from __future__ import annotations

import mujoco
import numpy as np

from muble import Pose

FINGERTIP_CLEARANCE = 0.015  # m the grip site stays above the table so the fingertips do not scrape it
PRE_GRASP = 0.10  # m back along the approach from the grasp pose where the straight move in starts


def _compose(pose_pos, pose_quat, pos, quat) -> tuple[np.ndarray, np.ndarray]:
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, pose_quat)
    out = np.empty(4)
    mujoco.mju_mulQuat(out, pose_quat, np.asarray(quat, dtype=float))
    return pose_pos + rot.reshape(3, 3) @ np.asarray(pos, dtype=float), out


def _turned(quat: np.ndarray, angle: float) -> np.ndarray:
    """``quat`` turned by ``angle`` about its own z axis (the approach direction)."""
    turn = np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, quat, turn)
    return out


def _axis(quat: np.ndarray, k: int) -> np.ndarray:
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, quat)
    return rot.reshape(3, 3)[:, k]


def grasp_approach(grasp: Pose) -> np.ndarray:
    """Unit vector along which the hand moves into the grasp (the grip site's z axis)."""
    return _axis(grasp.quat, 2)


def grasp_candidates(object_pose: Pose, model, table_top: float, max_width: float = np.inf,
                     rest_quat: np.ndarray | None = None) -> list[Pose]:
    """World grip-site poses for grasping, best first.

    A grasp frame is the grip site's pose in object coordinates (x: the fingers' closing direction, z: from the
    hand into the object). Frames whose width does not fit between the open fingers (``max_width``) are left
    out. Every frame is tried as given and turned half a turn about its approach axis (the fingers are
    symmetric, the wrist's limits are not); boxes, and cylinders gripped about their axis, also get the quarter
    turns, since those grasps work from any side. Top-down grasps come first, then those whose closing direction is nearest the hand's
    at ``rest_quat`` (less wrist travel).
    """
    rest_x = _axis(rest_quat, 0) if rest_quat is not None else None
    scored = []
    for index, frame in enumerate(model.grasp_frames):
        if frame.width > max_width:
            continue
        pos, quat = _compose(object_pose.pos, object_pose.quat, frame.position, frame.quat)
        pos[2] = max(pos[2], table_top + FINGERTIP_CLEARANCE)
        yaws = [0.0, np.pi]
        on_axis = float(np.hypot(frame.position[0], frame.position[1])) < 1e-3
        if model.grasp_type == "box" or (model.grasp_type == "cylinder" and on_axis):
            yaws += [np.pi / 2, -np.pi / 2]
        for yaw in yaws:
            q = _turned(quat, yaw)
            approach, closing = _axis(q, 2), _axis(q, 0)
            tilt = float(np.arccos(np.clip(-approach[2], -1.0, 1.0)))
            turn = float(np.arccos(min(1.0, abs(float(closing @ rest_x))))) if rest_x is not None else 0.0
            scored.append((tilt + 0.3 * turn + 0.002 * index, len(scored), Pose(pos.copy(), q)))
    scored.sort(key=lambda item: item[:2])
    return [pose for *_, pose in scored]


def footprint_radius(extents: np.ndarray) -> float:
    return 0.5 * float(np.hypot(extents[0], extents[1]))


def free_places(region: tuple[np.ndarray, np.ndarray], radius: float, others: list[tuple[np.ndarray, float]],
                gap: float = 0.02, spacing: float = 0.03) -> list[np.ndarray]:
    """Centres in ``region`` where a footprint of ``radius`` overlaps no other footprint (centre, radius),
    nearest the region's centre first."""
    lo, hi = region
    xs = np.arange(lo[0], hi[0] + 1e-9, spacing)
    ys = np.arange(lo[1], hi[1] + 1e-9, spacing)
    centre = 0.5 * (lo + hi)
    places = []
    for x in xs:
        for y in ys:
            p = np.array([x, y])
            if all(np.linalg.norm(p - c) >= radius + r + gap for c, r in others):
                places.append(p)
    places.sort(key=lambda p: float(np.linalg.norm(p - centre)))
    return places

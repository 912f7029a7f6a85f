"""Grasp and placement poses: from an object's grasp frames (object coordinates) to world poses of the hand,
and free places on the table for putting an object down.
"""
from __future__ import annotations

import mujoco
import numpy as np

from muble import Pose

FINGERTIP_CLEARANCE = 0.015  # m the grip site stays above the table so the fingertips do not scrape it
PRE_GRASP = 0.10  # m above the grasp pose where the straight descent starts


def _compose(pose_pos, pose_quat, pos, quat) -> tuple[np.ndarray, np.ndarray]:
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, pose_quat)
    out = np.empty(4)
    mujoco.mju_mulQuat(out, pose_quat, np.asarray(quat, dtype=float))
    return pose_pos + rot.reshape(3, 3) @ np.asarray(pos, dtype=float), out


def _yawed(quat: np.ndarray, yaw: float) -> np.ndarray:
    turn = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, turn, quat)
    return out


def grasp_candidates(object_pose: Pose, model, table_top: float) -> list[Pose]:
    """World grip-site poses for grasping, best first.

    Every grasp frame of the model is tried as given and turned half a turn about the vertical (the gripper is
    symmetric); cylinders and boxes also get the quarter turns, since their grasp works from any side.
    """
    yaws = [0.0, np.pi]
    if model.grasp_type in ("cylinder", "box"):
        yaws += [np.pi / 2, -np.pi / 2]
    poses = []
    for frame in model.grasp_frames:
        pos, quat = _compose(object_pose.pos, object_pose.quat, frame.position, frame.quat)
        pos[2] = max(pos[2], table_top + FINGERTIP_CLEARANCE)
        poses.extend(Pose(pos.copy(), _yawed(quat, yaw)) for yaw in yaws)
    return poses


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

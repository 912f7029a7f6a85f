"""Geometry shared by the simulation, the scene generator and the plugins: turns about the vertical, tilt from it,
and convex hulls of footprints on the table plane.

Quaternions are MuJoCo's and the scene graph's: (w, x, y, z). Rotations go through ``scipy.spatial.transform``.
"""
from __future__ import annotations

import functools
import math

import numpy as np


def yaw_quat(yaw: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a turn by ``yaw`` radians about world z."""
    return np.array(_yaw_quat(float(yaw)))


@functools.lru_cache(maxsize=4096)
def _yaw_quat(yaw: float) -> tuple[float, ...]:
    # Grasp ranking asks for the same few turns hundreds of times a scene; scipy's call costs more than the rest.
    from scipy.spatial.transform import Rotation

    return tuple(Rotation.from_euler("z", yaw).as_quat(scalar_first=True).tolist())


def yaw_matrix(yaw: float) -> np.ndarray:
    """3x3 rotation matrix of a turn by ``yaw`` radians about world z."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("z", yaw).as_matrix()


def tilt_deg(quat) -> float:
    """Degrees between the z axis of the frame turned by ``quat`` (w, x, y, z) and the world's vertical."""
    w, x, y, z = (float(v) for v in quat)
    return math.degrees(math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y)))))


def hull_2d(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of 2-D ``points``, counter-clockwise; all the points when they are degenerate
    (a point or a line)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return np.ascontiguousarray(points[ConvexHull(points).vertices])
    except (QhullError, ValueError):
        return np.ascontiguousarray(points)

"""Geometry shared by the simulation, the scene generator and the plugins: turns about the vertical, tilt from it,
turns between two orientations, rotation matrices of quaternions, the world box of a turned box, the vertices of
a collision mesh where it stands, and convex outlines on the table plane (hulls, distances).

Quaternions are MuJoCo's and the scene graph's: (w, x, y, z). Rotations go through ``scipy.spatial.transform``,
except ``quat_matrix`` (a closed form) and ``mujoco_quat_matrix`` (MuJoCo's own): each caller keeps the one it
has always used, since their last bits differ and grasps and placements are computed from them.
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


def quat_matrix(quat) -> np.ndarray:
    """3x3 rotation matrix of the quaternion ``quat`` (w, x, y, z; normalised first)."""
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def mujoco_quat_matrix(quat) -> np.ndarray:
    """3x3 rotation matrix of the quaternion ``quat`` (w, x, y, z) as MuJoCo computes it (``mju_quat2Mat``, not
    normalised): the same bits as the simulation's own poses."""
    import mujoco

    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float))
    return rot.reshape(3, 3)


def world_extents(size, quat) -> np.ndarray:
    """Full size along world x, y, z of the world-axis-aligned box that holds a box of object-frame extents
    ``size`` (x, y, z) turned by ``quat`` (w, x, y, z)."""
    return np.abs(quat_matrix(quat)) @ np.asarray(size, dtype=float)


def mesh_vertices(model, geom: int) -> np.ndarray:
    """The vertices (n x 3, the geom's own frame) of the mesh of MuJoCo mesh geom ``geom`` in ``model``."""
    mesh = model.geom_dataid[geom]
    start, n = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    return model.mesh_vert[start:start + n]


def geom_world_vertices(model, data, geom: int) -> np.ndarray:
    """World positions (n x 3) of the vertices of MuJoCo mesh geom ``geom`` as it stands in ``data``."""
    return mesh_vertices(model, geom) @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]


def tilt_deg(quat) -> float:
    """Degrees between the z axis of the frame turned by ``quat`` (w, x, y, z) and the world's vertical."""
    w, x, y, z = (float(v) for v in quat)
    return math.degrees(math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y)))))


def turn_deg(quat_a, quat_b) -> float:
    """Degrees of the rotation that takes the orientation ``quat_a`` to ``quat_b`` (unit quaternions, w, x, y, z)."""
    dot = min(1.0, abs(float(np.dot(quat_a, quat_b))))
    return math.degrees(2.0 * math.acos(dot))


def hull_2d(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of 2-D ``points``, counter-clockwise; all the points when they are degenerate
    (a point or a line)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return np.ascontiguousarray(points[ConvexHull(points).vertices])
    except (QhullError, ValueError):
        return np.ascontiguousarray(points)


def polygon_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Least distance between two convex polygons on the plane (vertices in order, n x 2); 0 when they overlap."""
    for poly in (a, b):  # separating axes: the normals of both polygons' edges
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(axis=0) < pb.min(axis=0)) | (pb.max(axis=0) < pa.min(axis=0))):
            break
    else:
        return 0.0
    return min(_points_to_edges(a, b), _points_to_edges(b, a))


def _points_to_edges(points: np.ndarray, poly: np.ndarray) -> float:
    """Least distance from any of ``points`` to any edge of the closed polygon ``poly``."""
    start, edge = poly, np.roll(poly, -1, axis=0) - poly
    rel = points[:, None, :] - start[None, :, :]
    t = np.clip((rel * edge).sum(axis=2) / np.maximum((edge * edge).sum(axis=1), 1e-18), 0.0, 1.0)
    return float(np.linalg.norm(rel - t[:, :, None] * edge[None], axis=2).min())

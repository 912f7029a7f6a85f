"""Rotations through scipy agree with the closed forms they replaced; footprint hulls."""
from __future__ import annotations

import math

import numpy as np

from muble.stage.camera import euler_xyz_to_matrix, matrix_to_euler_xyz, matrix_to_quat
from muble.stage.geometry import hull_2d, tilt_deg, yaw_matrix, yaw_quat


def _old_euler_xyz_to_matrix(angles_deg):
    ax, ay, az = np.radians(np.asarray(angles_deg, dtype=float))
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _old_matrix_to_euler_xyz(r):
    ay = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    return np.degrees([math.atan2(r[2, 1], r[2, 2]), ay, math.atan2(r[1, 0], r[0, 0])])


def _old_matrix_to_quat(r):
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax([r[0, 0], r[1, 1], r[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0, 0.0, 0.0, 0.0]
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    quat = np.array(q) / np.linalg.norm(q)
    return -quat if quat[0] < 0 else quat


def test_camera_rotations_match_the_closed_forms():
    rng = np.random.default_rng(0)
    for angles in np.c_[rng.uniform(-180, 180, 500), rng.uniform(-89, 89, 500), rng.uniform(-180, 180, 500)]:
        r = _old_euler_xyz_to_matrix(angles)
        assert np.allclose(euler_xyz_to_matrix(angles), r, rtol=0, atol=1e-12)
        assert np.allclose(matrix_to_euler_xyz(r), _old_matrix_to_euler_xyz(r), rtol=0, atol=1e-9)
        assert np.allclose(matrix_to_euler_xyz(r), angles, rtol=0, atol=1e-9)
        quat = matrix_to_quat(r)
        assert quat[0] >= 0 and np.allclose(quat, _old_matrix_to_quat(r), rtol=0, atol=1e-12)


def test_yaw_rotations_match_the_closed_forms():
    for yaw in np.random.default_rng(1).uniform(-2 * math.pi, 2 * math.pi, 500):
        c, s = math.cos(yaw), math.sin(yaw)
        # Generated scenes store this quaternion: it must stay the same to the bit.
        assert np.array_equal(yaw_quat(yaw), [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])
        assert np.allclose(yaw_matrix(yaw), [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], rtol=0, atol=1e-15)


def test_tilt_is_the_angle_of_the_turned_z_axis():
    from scipy.spatial.transform import Rotation

    for rot in Rotation.random(200, rng=np.random.default_rng(2)):
        z = rot.as_matrix()[:, 2]
        assert math.isclose(tilt_deg(rot.as_quat(scalar_first=True)), math.degrees(math.acos(z[2])), abs_tol=1e-6)
    assert tilt_deg(yaw_quat(1.0)) == 0.0


def test_hull_keeps_the_extreme_points_and_passes_degenerate_ones_through():
    points = np.random.default_rng(3).uniform(-1, 1, (200, 2))
    square = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    hull = hull_2d(np.vstack([points, square]))
    assert sorted(map(tuple, hull)) == sorted(map(tuple, square))
    edges = np.roll(hull, -1, axis=0) - hull
    assert np.all(edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0] > 0)
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    assert np.array_equal(hull_2d(line), line) and hull_2d(line).flags.c_contiguous

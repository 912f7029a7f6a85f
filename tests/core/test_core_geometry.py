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


def test_the_rotation_matrices_of_a_quaternion_are_muble_s_and_mujoco_s():
    """``quat_matrix`` (a closed form, normalising) and ``mujoco_quat_matrix`` (MuJoCo's ``mju_quat2Mat``, to the
    bit) are the same rotation; each caller keeps its own, since their last bits differ."""
    import mujoco
    from scipy.spatial.transform import Rotation

    from muble.stage.geometry import mujoco_quat_matrix, quat_matrix

    for rot in Rotation.random(300, rng=np.random.default_rng(4)):
        quat = rot.as_quat(scalar_first=True)
        own = np.empty(9)
        mujoco.mju_quat2Mat(own, quat)
        assert np.array_equal(mujoco_quat_matrix(quat), own.reshape(3, 3))
        assert np.allclose(quat_matrix(quat), rot.as_matrix(), rtol=0, atol=1e-12)
        assert np.allclose(mujoco_quat_matrix(quat), rot.as_matrix(), rtol=0, atol=1e-12)
    assert np.allclose(quat_matrix([2.0, 0.0, 0.0, 0.0]), np.eye(3))  # normalised first


def test_a_mesh_geom_s_world_vertices_are_where_mujoco_puts_the_geom():
    """The vertices of a collision mesh where it stands: the mesh's own vertices turned and moved by the geom's
    world frame (MuJoCo's ``geom_xmat``, ``geom_xpos``), the same bits as the expression each caller wrote before;
    the lowest z plus the geom's height, as one caller took it, is the lowest world z to the bit."""
    import mujoco

    from muble.stage.geometry import geom_world_vertices, mesh_vertices

    tetra = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.03]]
    xml = f"""<mujoco><asset><mesh name="m" vertex="{' '.join(str(v) for p in tetra for v in p)}"/></asset>
    <worldbody><body pos="0.4 -0.2 0.8" euler="20 -35 70"><freejoint/>
    <geom name="g" type="mesh" mesh="m" pos="0.01 0.02 -0.03" euler="5 10 15"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    g = model.geom("g").id
    local = mesh_vertices(model, g)
    assert local.shape == (4, 3)
    world = geom_world_vertices(model, data, g)
    rot, pos = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
    assert np.array_equal(world, local @ rot.T + pos)
    assert np.allclose(world, [pos + rot @ v for v in local], rtol=0, atol=1e-12)
    # MuJoCo recentres a mesh on its centre of mass and stores it in single precision: its local vertices are the
    # tetrahedron's moved and turned, so the edge lengths are kept.
    edges = [np.linalg.norm(np.subtract(tetra[i], tetra[j])) for i in range(4) for j in range(i + 1, 4)]
    found = [np.linalg.norm(world[i] - world[j]) for i in range(4) for j in range(i + 1, 4)]
    assert np.allclose(sorted(found), sorted(edges), rtol=0, atol=1e-6)
    assert float(world[:, 2].min()) == float((local @ rot.T)[:, 2].min() + pos[2])
    rng = np.random.default_rng(5)
    for _ in range(2000):  # adding is monotone: the least sum is the least term's sum, whatever the rounding
        terms, shift = rng.uniform(-1.0, 1.0, 50) * 10.0 ** rng.uniform(-3, 1), rng.uniform(-2.0, 2.0)
        assert float((terms + shift).min()) == float(terms.min() + shift)

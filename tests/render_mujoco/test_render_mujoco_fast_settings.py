"""The MuJoCo renderer's settings for small, fast images: simplified meshes, no reflection or multisampling, an
offscreen buffer the image's size. The model is left as compiled; the masks stay close to the meshes' own."""
from __future__ import annotations

import numpy as np
import pytest

from muble import SEG_ROBOT, ConfigError, get_registry
from muble_plugins.renderers.mujoco import MujocoRenderer
from muble_plugins.renderers.mujoco.simplify import decimate, deviation

pytestmark = pytest.mark.gl

SMALL = {"width": 128, "height": 128}


def _frame(env, **options):
    renderer = get_registry().create("renderer", "mujoco", {**SMALL, **options})
    try:
        renderer.setup(env.sync_scene_graph(), env.model)
        return renderer.render(env.data, env.names.cameras["front"])
    finally:
        renderer.close()


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def _surface_distances(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each point's distance to the nearest of all the triangles (brute force, for small meshes)."""
    from trimesh.triangles import closest_point

    triangles = verts[faces]
    pairs_t = np.tile(triangles, (len(points), 1, 1))
    pairs_p = np.repeat(points, len(triangles), axis=0)
    gaps = np.linalg.norm(closest_point(pairs_t, pairs_p) - pairs_p, axis=1)
    return gaps.reshape(len(points), len(triangles)).min(axis=1)


def _capsule_mesh(radius: float, length: float):
    import trimesh

    mesh = trimesh.creation.capsule(height=length, radius=radius, count=[48, 48])
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_decimation_keeps_every_vertex_within_the_tolerance_and_the_tolerance_decides_the_reduction():
    # A finely tessellated capsule as a mesh is stored for drawing: a vertex per triangle corner.
    verts, faces = _capsule_mesh(radius=0.03, length=0.2)
    corners = verts[faces].reshape(-1, 3)
    stored_faces = np.arange(len(corners)).reshape(-1, 3)
    loose = decimate(corners, stored_faces, tolerance=0.003)
    tight = decimate(corners, stored_faces, tolerance=0.0003)
    assert loose is not None and tight is not None
    # The coincident corners were welded: the decimation found a closed surface and removed most triangles.
    assert len(loose[1]) <= 0.2 * len(faces)
    # A tighter tolerance keeps more of them, and each copy stays within its own tolerance of every vertex.
    assert len(tight[1]) > len(loose[1]) and tight[3] < loose[3]
    for (out_verts, out_faces, normals, _), tolerance in ((loose, 0.003), (tight, 0.0003)):
        assert _surface_distances(verts, out_verts, out_faces).max() <= tolerance + 1e-9
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-9)
        # Outward normals on the capsule's round end: away from its centre.
        tip = out_verts[:, 2].argmax()
        assert normals[tip, 2] > 0.9
    # The measured deviation bounds the true one (it is never smaller than the brute-force distance).
    out_verts, out_faces = loose[0], loose[1]
    assert deviation(verts, out_verts, out_faces) >= _surface_distances(verts, out_verts, out_faces).max() - 1e-12


def test_fast_settings_keep_the_masks_and_leave_the_model_as_compiled(generated_env):
    model = generated_env.model
    before = (model.mesh_vert.copy(), model.mesh_face.copy(), model.mesh_facenum.copy(),
              int(model.vis.global_.offwidth), int(model.vis.quality.offsamples))
    detailed = _frame(generated_env)
    fast = _frame(generated_env, shadows=False, reflection=False, multisamples=0, mesh_tolerance=0.005)
    assert _iou(detailed.mask(SEG_ROBOT), fast.mask(SEG_ROBOT)) > 0.95
    visible = [obj.id for obj in generated_env.scene.objects if detailed.mask(obj.id).any()]
    assert visible
    for obj_id in visible:
        assert _iou(detailed.mask(obj_id), fast.mask(obj_id)) > 0.95
    # The simplified meshes reached the drawing: some robot pixels move.
    assert not np.array_equal(detailed.segmentation, fast.segmentation)
    np.testing.assert_array_equal(model.mesh_vert, before[0])
    np.testing.assert_array_equal(model.mesh_face, before[1])
    np.testing.assert_array_equal(model.mesh_facenum, before[2])
    assert (int(model.vis.global_.offwidth), int(model.vis.quality.offsamples)) == before[3:]
    # Drawn again as modelled, the same pixels as the first time.
    np.testing.assert_array_equal(_frame(generated_env).rgb, detailed.rgb)


def test_out_of_range_settings_are_refused():
    with pytest.raises(ConfigError, match=r"mesh_tolerance must be > 0 and <= 0\.05 .*got 0\.5"):
        get_registry().create("renderer", "mujoco", {"mesh_tolerance": 0.5})
    with pytest.raises(ConfigError, match="multisamples must be 0..16"):
        get_registry().create("renderer", "mujoco", {"multisamples": 64})
    # Built directly, the renderer checks the same schema.
    with pytest.raises(ConfigError, match="multisamples must be 0..16"):
        MujocoRenderer(multisamples=64)

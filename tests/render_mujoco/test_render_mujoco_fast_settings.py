"""The MuJoCo renderer's settings for small, fast images: simplified meshes, no reflection or multisampling, an
offscreen buffer the image's size. The model is left as compiled; the masks stay close to the meshes' own."""
from __future__ import annotations

import numpy as np
import pytest

from muble import SEG_ROBOT, RenderError, get_registry
from muble_plugins.renderers.mujoco.simplify import cluster_vertices

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


def test_clustering_keeps_vertices_within_a_cell_and_drops_collapsed_triangles():
    # A finely tessellated unit square: 2 x 20 x 20 triangles.
    n = 21
    xs, ys = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    verts = np.stack([xs.ravel(), ys.ravel(), np.zeros(n * n)], axis=1)
    quads = [(i * n + j, i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j) for i in range(n - 1) for j in range(n - 1)]
    faces = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    out_verts, out_faces, normals = cluster_vertices(verts, faces, cell=0.25)
    assert 0 < len(out_faces) < len(faces) / 10
    # Every new vertex is the mean of one cell's vertices, so lies within it; the square stays flat and faces up.
    assert out_verts[:, :2].min() >= 0 and out_verts[:, :2].max() <= 1
    np.testing.assert_allclose(out_verts[:, 2], 0)
    np.testing.assert_allclose(normals, np.tile([0, 0, 1], (len(normals), 1)), atol=1e-9)
    assert len({tuple(sorted(f)) for f in out_faces.tolist()}) == len(out_faces)


def test_fast_settings_keep_the_masks_and_leave_the_model_as_compiled(generated_env):
    model = generated_env.model
    before = (model.mesh_vert.copy(), model.mesh_face.copy(), model.mesh_facenum.copy(),
              int(model.vis.global_.offwidth), int(model.vis.quality.offsamples))
    detailed = _frame(generated_env)
    fast = _frame(generated_env, shadows=False, reflection=False, multisamples=0, mesh_cell=0.01)
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
    with pytest.raises(RenderError, match="mesh_cell"):
        get_registry().create("renderer", "mujoco", {"mesh_cell": 0.5})
    with pytest.raises(RenderError, match="multisamples"):
        get_registry().create("renderer", "mujoco", {"multisamples": 64})

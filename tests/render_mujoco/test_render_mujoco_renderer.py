"""The MuJoCo renderer against independent geometry: projected meshes, ray-plane depth, label mapping."""
from __future__ import annotations


import mujoco
import numpy as np
import pytest
from PIL import Image, ImageDraw

from muble import SEG_BACKGROUND, SEG_TABLE, RenderError, get_registry
from muble.generation.checks import CAMERA_NAME, view_model
from muble.stage.camera import CameraParams
from muble.stage.layout import Placement

pytestmark = pytest.mark.gl

TABLE_X, TABLE_Y = (0.0, 0.9), (-0.6, 0.6)



@pytest.fixture(scope="module")
def renderer():
    r = get_registry().create("renderer", "mujoco", {"width": 848, "height": 480})
    yield r
    r.close()


def _model(object_set, category, seed):
    return object_set.build(object_set.sample(np.random.default_rng(seed), category))


def projected_silhouette(camera: CameraParams, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The union of the mesh's projected triangles, filled by PIL (pixel centres at +0.5 as in OpenGL)."""
    uvd = camera.project(vertices)
    image = Image.new("1", (camera.width, camera.height), 0)
    draw = ImageDraw.Draw(image)
    for tri in faces:
        pts = [(float(uvd[k, 0]) - 0.5, float(uvd[k, 1]) - 0.5) for k in tri]
        draw.polygon(pts, fill=1)
    return np.array(image, dtype=bool)


@pytest.mark.parametrize("category,seed,x,y,yaw", [
    ("mug", 1, 0.5, -0.1, 0.7), ("bowl", 2, 0.35, 0.05, 0.0), ("baking tray", 3, 0.62, -0.25, 2.0),
    ("wine glass", 4, 0.45, -0.3, -1.0),
])
def test_object_mask_matches_projected_mesh(object_set, renderer, category, seed, x, y, yaw):
    camera = CameraParams()
    model = _model(object_set, category, seed)
    placement = Placement(x, y, yaw)
    view, data = view_model([model], [placement], camera, TABLE_X, TABLE_Y)
    renderer.setup(None, view)
    frame = renderer.render(data, CAMERA_NAME)
    rendered = frame.mask(0)
    expected = projected_silhouette(camera, placement.transform(model.visual.vertices), model.visual.faces)
    iou = (rendered & expected).sum() / (rendered | expected).sum()
    assert rendered.sum() > 500
    assert iou >= 0.95, f"{category}: IoU {iou:.3f}"


def test_depth_is_metric_along_the_view_axis(renderer, object_set):
    camera = CameraParams()
    view, data = view_model([], [], camera, TABLE_X, TABLE_Y)
    renderer.setup(None, view)
    frame = renderer.render(data, CAMERA_NAME)
    # Independent: intersect the pixel rays with the table plane z = 0 and take the depth along the axis.
    f = camera.focal_px
    for row, col in [(300, 300), (400, 424), (470, 700)]:
        assert frame.segmentation[row, col] == SEG_TABLE
        ray_cam = np.array([(col + 0.5 - camera.width / 2) / f, -(row + 0.5 - camera.height / 2) / f, -1.0])
        ray = camera.rotation @ ray_cam
        t = -camera.position[2] / ray[2]
        assert frame.depth[row, col] == pytest.approx(t, abs=2e-3)
    assert frame.segmentation[5, 424] == SEG_BACKGROUND  # above the horizon of the table


def test_camera_pose_in_mujoco_equals_the_blender_parameters():
    camera = CameraParams.from_scene_params({"position": [1.0, -0.2, 0.3], "rotation": [80.0, 5.0, 95.0],
                                             "rotation_mode": "EulerXYZ"})
    view, data = view_model([], [], camera, TABLE_X, TABLE_Y)
    assert np.allclose(data.cam_xmat[0].reshape(3, 3), camera.rotation, atol=1e-6)
    assert np.allclose(data.cam_xpos[0], camera.position)
    assert view.cam_fovy[0] == pytest.approx(camera.fovy_deg)
    assert np.allclose(camera.euler_xyz_deg, [80.0, 5.0, 95.0])
    # Blender's default SHOP-VRB2 lens: 26 mm on a 36 mm sensor at 848 px is 612 px.
    assert CameraParams().focal_px == pytest.approx(612.4, abs=0.1)


def test_shared_mesh_atlas_draws_like_a_fresh_context(object_set, renderer):
    camera = CameraParams()
    models = [_model(object_set, c, 10 + i) for i, c in enumerate(["mug", "plate", "soda can"])]
    placements = [Placement(0.4, -0.2, 0.3), Placement(0.6, 0.0, 1.0), Placement(0.35, 0.05, 2.0)]
    view, data = view_model(models, placements, camera, TABLE_X, TABLE_Y)
    renderer.setup(None, view)
    shared = renderer.render(data, CAMERA_NAME).segmentation
    own = get_registry().create("renderer", "mujoco", {"width": 848, "height": 480, "reuse_meshes": False})
    try:
        own.setup(None, view)
        fresh = own.render(data, CAMERA_NAME)
    finally:
        own.close()
    assert (shared == fresh.segmentation).mean() > 0.9999
    assert set(np.unique(shared)) >= {0, 1, 2, SEG_TABLE, SEG_BACKGROUND}
    assert fresh.rgb.shape == (480, 848, 3) and fresh.rgb.std() > 5


def test_unknown_camera_lists_the_valid_ones(renderer):
    view, data = view_model([], [], CameraParams(), TABLE_X, TABLE_Y)
    renderer.setup(None, view)
    with pytest.raises(RenderError, match="valid camera names: front"):
        renderer.render(data, "side")


def test_labels_follow_object_table_and_robot_names():
    from muble_plugins.renderers.mujoco.labels import geom_labels
    from muble import SEG_ROBOT

    xml = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
      <geom name="table_top" type="box" size=".1 .1 .1"/>
      <body name="obj3"><geom name="obj3_visual" type="sphere" size=".01"/>
        <body name="inner"><geom type="sphere" size=".01"/></body></body>
      <body name="object7"><geom type="sphere" size=".01"/></body>
      <body name="robot0_link1"><geom type="sphere" size=".01"/></body>
      <body name="gripper0_finger"><geom type="sphere" size=".01"/></body></worldbody></mujoco>"""
    labels = geom_labels(mujoco.MjModel.from_xml_string(xml)).tolist()
    assert labels == [SEG_BACKGROUND, SEG_TABLE, 3, 3, 7, SEG_ROBOT, SEG_ROBOT]


def test_a_kept_renderer_refills_its_context_for_a_new_scene_and_draws_as_a_fresh_one():
    """Scenes of one stage (arena, robot, textures) share a GL context: only the mesh slots whose contents differ
    are uploaded again, and RGB (with shadows), depth and labels are the same as a fresh renderer's."""
    from muble.app.config import compose
    from muble.episode.components import build_components, generated_env

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp"])
    components = build_components(cfg, renderer=False, task=False)
    envs = [generated_env(cfg, components, i) for i in (0, 4)]  # 113 and 120 meshes: the larger one first
    envs.sort(key=lambda e: -e.model.nmesh)
    kept = get_registry().create("renderer", "mujoco", {"width": 320, "height": 240})
    try:
        contexts = []
        for env in envs:
            scene = env.sync_scene_graph()
            kept.setup(scene, env.model)
            contexts.append(kept._context)
            drawn = kept.render(env.data, "front")
            own = get_registry().create("renderer", "mujoco", {"width": 320, "height": 240})
            try:
                own.setup(scene, env.model)
                fresh = own.render(env.data, "front")
            finally:
                own.close()
            for part in ("rgb", "depth", "segmentation"):
                np.testing.assert_array_equal(getattr(drawn, part), getattr(fresh, part), err_msg=part)
        assert contexts[0] is contexts[1], "the second scene was given a new context instead of refilled slots"
    finally:
        kept.close()
        for env in envs:
            env.close()

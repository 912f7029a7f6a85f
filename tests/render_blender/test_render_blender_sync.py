"""Blender and MuJoCo see the same state through the same camera: masks and depth line up."""
import numpy as np
import pytest

from muble import SEG_ROBOT, SEG_TABLE, Frame, RenderError
from muble_plugins.renderers.blender.labels import geom_labels
from muble_plugins.renderers.render_world import build_world, random_scene

pytestmark = pytest.mark.blender


@pytest.mark.parametrize("seed,camera", [(0, "frontview"), (1, "agentview"), (2, "frontview")])
def test_segmentation_and_depth_match_mujoco(blender_renderer, mujoco_reference, seed, camera):
    scene = random_scene(np.random.default_rng(seed), n_objects=4, image_index=seed)
    model, data = build_world(scene, arm_seed=seed)
    blender_renderer.setup(scene, model)
    frame = blender_renderer.render(data, camera)
    assert isinstance(frame, Frame) and frame.rgb.shape == (120, 160, 3) and frame.rgb.dtype == np.uint8
    ref_seg, ref_depth = mujoco_reference(model, data, camera, 160, 120, geom_labels(model, scene))
    labels = [SEG_TABLE, *scene.ids] + ([SEG_ROBOT] if (ref_seg == SEG_ROBOT).sum() > 20 else [])
    for label in labels:
        ours, ref = frame.mask(label), ref_seg == label
        assert ref.sum() > 0, f"label {label} invisible in MuJoCo's view; the test world is wrong"
        iou = (ours & ref).sum() / (ours | ref).sum()
        assert iou >= 0.9, f"label {label}: IoU {iou:.3f} between Blender and MuJoCo"
    on_objects = ref_seg >= 0
    assert np.median(np.abs(frame.depth - ref_depth)[on_objects]) < 0.01


def test_keyframes_follow_the_state(blender_renderer, mujoco_reference):
    """Moving an object in MuJoCo moves it in the next keyframe, without a new setup."""
    import mujoco

    scene = random_scene(np.random.default_rng(5), n_objects=2)
    model, data = build_world(scene)
    blender_renderer.setup(scene, model)
    before = blender_renderer.render(data, "agentview").mask(0)
    joint = model.body("obj0_main").jntadr[0]
    data.qpos[model.jnt_qposadr[joint] + 1] += 0.15  # 15 cm along y
    mujoco.mj_forward(model, data)
    after = blender_renderer.render(data, "agentview")
    ref_seg, _ = mujoco_reference(model, data, "agentview", 160, 120, geom_labels(model, scene))
    moved = after.mask(0)
    assert (before & moved).sum() < 0.5 * moved.sum()
    assert (moved & (ref_seg == 0)).sum() / (moved | (ref_seg == 0)).sum() >= 0.9


def test_unknown_camera_lists_the_valid_ones(blender_renderer):
    scene = random_scene(np.random.default_rng(0), n_objects=1)
    model, data = build_world(scene)
    blender_renderer.setup(scene, model)
    with pytest.raises(RenderError, match="valid camera names: .*agentview"):
        blender_renderer.render(data, "nosuchcam")

"""One frame geometry: on a generated scene, Blender's and MuJoCo's default frames line up pixel for pixel."""
from __future__ import annotations

import pytest

from muble import SEG_ROBOT, SEG_TABLE, get_registry
from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH

pytestmark = pytest.mark.blender


def test_both_renderers_default_to_the_shopvrb2_image():
    from muble_plugins.renderers.blender.config import BlenderRendererConfig
    from muble_plugins.renderers.mujoco import MujocoRendererConfig

    for cfg in (BlenderRendererConfig(), MujocoRendererConfig()):
        assert (cfg.width, cfg.height) == (DEFAULT_WIDTH, DEFAULT_HEIGHT) == (848, 480)


def test_object_masks_agree_on_a_generated_scene(generated_env):
    from muble_plugins.renderers.blender import BlenderRenderer

    width, height = DEFAULT_WIDTH // 4, DEFAULT_HEIGHT // 4  # same frame, fewer pixels: masks need no more
    env, scene = generated_env, generated_env.scene
    blender = BlenderRenderer(width=width, height=height, samples=1, denoise=False)
    mujoco_renderer = get_registry().create("renderer", "mujoco", {"width": width, "height": height})
    try:
        camera = env.names.cameras["front"]
        graph = env.sync_scene_graph()
        blender.setup(graph, env.model)
        mujoco_renderer.setup(graph, env.model)
        ours = blender.render(env.data, camera).segmentation
        ref = mujoco_renderer.render(env.data, camera).segmentation
    finally:
        blender.close()
        mujoco_renderer.close()
    scored = 0
    for label in [SEG_ROBOT, SEG_TABLE, *scene.ids]:
        reference = ref == label
        if reference.sum() < 10:
            continue
        mask = ours == label
        iou = (mask & reference).sum() / (mask | reference).sum()
        assert iou >= 0.9, f"label {label}: IoU {iou:.3f} between Blender and MuJoCo"
        scored += label >= 0
    assert scored >= 2, "the generated scene shows too few objects to compare"

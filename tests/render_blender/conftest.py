import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")


def mujoco_reference(model, data, camera, width, height, labels):
    """Segmentation labels and depth from MuJoCo's own renderer, drawing the same geom group (1)."""
    import mujoco

    from muble import SEG_BACKGROUND

    renderer = mujoco.Renderer(model, height, width)
    try:
        option = mujoco.MjvOption()
        option.geomgroup[:] = 0
        option.geomgroup[1] = 1
        renderer.update_scene(data, camera, scene_option=option)
        renderer.enable_segmentation_rendering()
        seg = renderer.render().copy()
        renderer.disable_segmentation_rendering()
        renderer.enable_depth_rendering()
        depth = renderer.render().copy()
        renderer.disable_depth_rendering()
    finally:
        renderer.close()
    ids, types = seg[..., 0], seg[..., 1]
    ref = np.full(ids.shape, SEG_BACKGROUND, dtype=np.int32)
    hit = (types == mujoco.mjtObj.mjOBJ_GEOM) & (ids >= 0)
    ref[hit] = labels[ids[hit]]
    return ref, depth


@pytest.fixture(name="mujoco_reference")
def mujoco_reference_fixture():
    return mujoco_reference


@pytest.fixture(scope="module")
def blender_renderer():
    from muble_plugins.renderers.blender import BlenderRenderer

    renderer = BlenderRenderer(width=160, height=120, samples=4, denoise=False)
    yield renderer
    renderer.close()

import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture(name="mujoco_reference")
def mujoco_reference_fixture():
    from tests.support.render_check import mujoco_reference

    return mujoco_reference


@pytest.fixture(scope="module")
def blender_renderer():
    from muble_plugins.renderers.blender import BlenderRenderer

    renderer = BlenderRenderer(width=160, height=120, samples=4, denoise=False)
    yield renderer
    renderer.close()

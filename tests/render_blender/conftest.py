import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture(name="mujoco_reference")
def mujoco_reference_fixture():
    from muble_plugins.renderers.blender.testing import mujoco_reference

    return mujoco_reference


@pytest.fixture(scope="module")
def blender_renderer():
    from muble_plugins.renderers.blender import BlenderRenderer

    renderer = BlenderRenderer(width=160, height=120, samples=4, denoise=False)
    yield renderer
    renderer.close()


@pytest.fixture(name="generated_env")
def generated_env_fixture():
    """The environment of generated scene 3 (the run config's generator, object set and robot), closed after."""
    from omegaconf import OmegaConf

    from muble.app.config import compose
    from muble.app.run import build_components, scene_generator
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp"])
    components = build_components(cfg, renderer=False, task=False)
    generator = scene_generator(cfg, components["object_set"])
    try:
        scene = generator.generate(3)
    finally:
        generator.close()
    env = TabletopEnv(scene, object_models(scene, components["object_set"], cfg.objects.name),
                      OmegaConf.to_container(cfg.robot, resolve=True), {})
    yield env
    env.close()

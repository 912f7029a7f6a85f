"""Shared test fixtures."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

REPO_ROOT = Path(__file__).resolve().parents[1]
REFERENCE_DIR = REPO_ROOT.parent / "shared" / "reference" / "muble-demo"


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    """The original SHOP-VRB2/MuBlE release files (kept beside the repository, never copied into it)."""
    if not REFERENCE_DIR.is_dir():
        pytest.skip(f"reference files not found at {REFERENCE_DIR}")
    return REFERENCE_DIR


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

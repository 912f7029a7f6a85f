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
    from muble.app.config import compose
    from muble.episode.components import build_components, generated_env

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp"])
    env = generated_env(cfg, build_components(cfg, renderer=False, task=False), 3)
    yield env
    env.close()

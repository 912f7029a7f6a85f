"""Shared test fixtures."""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Callable, Iterator

import pytest

from muble.plugins.manager import make_plugin_manager
from muble.plugins.registry import Registry
from tests.support.plugins import clear_caches, write_distribution

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


@pytest.fixture(scope="module")
def object_set():
    """The built-in SHOP-VRB2 object set, built once per test module."""
    from muble import get_registry

    return get_registry().create("object_set", "shopvrb2")


@pytest.fixture
def clear_hydra():
    """Hydra's global state cleared before and after the test (tests that compose configs themselves)."""
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    yield
    GlobalHydra.instance().clear()


@pytest.fixture
def muble_registry() -> Iterator[Registry]:
    """A fresh registry built from the installed entry points (no cached state)."""
    clear_caches()
    yield Registry(make_plugin_manager())
    clear_caches()


@pytest.fixture
def fake_distribution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[..., Path]]:
    """A factory that writes an installed-looking distribution (dist-info with entry points, plus modules) into a
    temporary folder on ``sys.path``, so a test exercises real entry-point discovery."""
    added: list[str] = []

    def make(name: str, entry_points: dict[str, str], modules: dict[str, str]) -> Path:
        root = write_distribution(tmp_path / f"site-{name}", name, entry_points, modules)
        monkeypatch.syspath_prepend(str(root))
        added.extend(m.split(".")[0] for m in modules)
        clear_caches()
        return root

    yield make
    for module in set(added):
        for key in [k for k in sys.modules if k == module or k.startswith(module + ".")]:
            del sys.modules[key]
    clear_caches()

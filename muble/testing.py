"""Test helpers for MuBlE and for authors of third-party plugins (loaded as a pytest plugin).

Fixtures:
- ``muble_registry``: a fresh registry built from the installed entry points (no cached state).
- ``fake_distribution``: a factory that writes an installed-looking distribution (dist-info with entry points,
  plus modules) into a temporary folder on ``sys.path``, so a test can exercise real entry-point discovery.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable, Iterator

import pytest

from muble.plugins.manager import ENTRY_POINT_GROUP, get_plugin_manager, make_plugin_manager
from muble.plugins.registry import Registry, get_registry


def write_distribution(root: Path, name: str, entry_points: dict[str, str], modules: dict[str, str],
                       version: str = "0.1.0") -> Path:
    """Write modules and a ``<name>-<version>.dist-info`` declaring ``entry_points`` in the ``muble`` group."""
    root.mkdir(parents=True, exist_ok=True)
    dist_info = root / f"{name.replace('-', '_')}-{version}.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    lines = [f"[{ENTRY_POINT_GROUP}]"] + [f"{k} = {v}" for k, v in entry_points.items()]
    (dist_info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    for module, source in modules.items():
        path = root / (module.replace(".", "/") + ".py")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
    return root


def clear_caches() -> None:
    """Forget the cached plugin manager and registry (after installing or removing plugins)."""
    get_registry.cache_clear()
    get_plugin_manager.cache_clear()


@pytest.fixture
def muble_registry() -> Iterator[Registry]:
    clear_caches()
    yield Registry(make_plugin_manager())
    clear_caches()


@pytest.fixture
def fake_distribution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[..., Path]]:
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

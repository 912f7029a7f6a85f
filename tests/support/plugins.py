"""Installed-looking plugin distributions for tests of entry-point discovery, and a reset of the cached plugin
manager and registry."""
from __future__ import annotations

from pathlib import Path

from muble.plugins.manager import ENTRY_POINT_GROUP, get_plugin_manager
from muble.plugins.registry import get_registry


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

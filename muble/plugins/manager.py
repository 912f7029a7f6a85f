"""The plugin manager: built by a cached function (never at import) so tests can make fresh ones."""
from __future__ import annotations

import functools
import logging
import os
from importlib import metadata

import pluggy

from muble.core.errors import PluginError
from muble.plugins import hookspecs

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "muble"
DISABLE_AUTOLOAD_ENV = "MUBLE_DISABLE_PLUGIN_AUTOLOAD"
PLUGINS_ENV = "MUBLE_PLUGINS"  # comma-separated entry point names to load even when autoload is disabled
BUILTIN_DISTRIBUTION = "muble"


def _entry_points() -> list[metadata.EntryPoint]:
    return sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (ep.dist.name if ep.dist else "", ep.name))


def _wanted(ep: metadata.EntryPoint) -> bool:
    """Built-ins always load; external plugins unless autoload is disabled (then only those in MUBLE_PLUGINS)."""
    dist = ep.dist.name if ep.dist else ""
    if dist == BUILTIN_DISTRIBUTION:
        return True
    if os.environ.get(DISABLE_AUTOLOAD_ENV, "") not in ("", "0"):
        requested = {n.strip() for n in os.environ.get(PLUGINS_ENV, "").split(",") if n.strip()}
        return ep.name in requested
    return True


class MublePluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers which distribution provided each plugin."""

    def __init__(self) -> None:
        super().__init__(ENTRY_POINT_GROUP)
        self.distributions: dict[str, str] = {}

    def distribution_of(self, plugin_name: str) -> str:
        return self.distributions.get(plugin_name, "(registered in code)")


def make_plugin_manager(extra_plugins: tuple[object, ...] = ()) -> MublePluginManager:
    """A fresh plugin manager with every wanted entry point loaded, plus ``extra_plugins`` (modules or objects)."""
    pm = MublePluginManager()
    pm.add_hookspecs(hookspecs)
    for ep in _entry_points():
        if not _wanted(ep) or pm.has_plugin(ep.name):
            continue
        dist = ep.dist.name if ep.dist else "?"
        try:
            plugin = ep.load()
        except Exception as e:  # an import error must name the plugin, whatever it was
            raise PluginError(
                f"plugin '{ep.name}' (entry point {ep.value} from distribution '{dist}') failed to import: "
                f"{type(e).__name__}: {e}. Fix or uninstall that package, or set {DISABLE_AUTOLOAD_ENV}=1"
            ) from e
        pm.register(plugin, name=ep.name)
        pm.distributions[ep.name] = dist
        log.debug("loaded plugin %s from %s", ep.name, dist)
    for i, plugin in enumerate(extra_plugins):
        pm.register(plugin, name=getattr(plugin, "__name__", f"extra-{i}"))
    pm.check_pending()
    return pm


@functools.cache
def get_plugin_manager() -> MublePluginManager:
    """The process-wide plugin manager (built on first use). ``get_plugin_manager.cache_clear()`` resets it."""
    return make_plugin_manager()

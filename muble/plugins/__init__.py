"""Plugin machinery: hook specifications, the plugin manager and the registry."""
from muble.plugins.hookspecs import hookimpl
from muble.plugins.manager import ENTRY_POINT_GROUP, get_plugin_manager, make_plugin_manager
from muble.plugins.records import KINDS, PluginRecord, Provided
from muble.plugins.registry import Registry, get_registry

__all__ = ["ENTRY_POINT_GROUP", "KINDS", "PluginRecord", "Provided", "Registry", "get_plugin_manager",
           "get_registry", "hookimpl", "make_plugin_manager"]

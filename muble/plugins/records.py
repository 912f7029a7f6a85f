"""Typed records that registration hooks return."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

# Plugin kinds, one per core interface, and the hook that registers each.
KINDS: dict[str, str] = {
    "renderer": "muble_register_renderers",
    "planner": "muble_register_planners",
    "primitive": "muble_register_primitives",
    "sensor": "muble_register_sensors",
    "task": "muble_register_tasks",
    "object_set": "muble_register_object_sets",
    "agent": "muble_register_agents",
    "trainer": "muble_register_trainers",
    "disturbance": "muble_register_disturbances",
    "property": "muble_register_properties",
}


@dataclass(frozen=True)
class PluginRecord:
    """One registered implementation.

    ``factory`` is the class (or a callable) that builds it; ``config`` is an optional dataclass describing its
    options, the one place their defaults and bounds (``muble.bounded``) are declared: the registry merges the
    given options onto it and rejects a mistyped key, a wrong type or a value out of range before anything is
    built. With ``takes_config`` the factory is called with that checked instance (``factory(config)``); otherwise
    with its fields as keyword arguments.
    """

    name: str
    factory: Callable[..., Any]
    description: str = ""
    config: type | None = None
    takes_config: bool = False


@dataclass(frozen=True)
class Provided:
    """A record together with the plugin (and distribution) that provided it."""

    kind: str
    record: PluginRecord
    plugin: str
    distribution: str

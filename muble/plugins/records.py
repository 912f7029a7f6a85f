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
}


@dataclass(frozen=True)
class PluginRecord:
    """One registered implementation.

    ``factory`` is the class (or a callable) that builds it from keyword arguments; ``config`` is an optional
    dataclass describing those arguments, used to reject mistyped keys before anything is built.
    """

    name: str
    factory: Callable[..., Any]
    description: str = ""
    config: type | None = None


@dataclass(frozen=True)
class Provided:
    """A record together with the plugin (and distribution) that provided it."""

    kind: str
    record: PluginRecord
    plugin: str
    distribution: str

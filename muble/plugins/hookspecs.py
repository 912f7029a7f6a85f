"""Every MuBlE hook. Implement them in a module registered under the ``muble`` entry point group::

    import muble

    @muble.hookimpl
    def muble_register_sensors():
        return [muble.PluginRecord("thermometer", Thermometer, "reads the table temperature")]

Registration hooks return lists of ``PluginRecord``; they never mutate global state.
"""
from __future__ import annotations

import pluggy

from muble.plugins.records import PluginRecord

hookspec = pluggy.HookspecMarker("muble")
hookimpl = pluggy.HookimplMarker("muble")
"""Marks a plugin's implementation of a hook below (``@muble.hookimpl``)."""


@hookspec
def muble_register_renderers() -> list[PluginRecord]:
    """Renderers (``muble.core.interfaces.Renderer``), e.g. ``PluginRecord("mujoco", MujocoRenderer)``."""


@hookspec
def muble_register_planners() -> list[PluginRecord]:
    """Motion planners (``MotionPlanner``), e.g. ``PluginRecord("ompl", OmplPlanner, config=OmplConfig)``."""


@hookspec
def muble_register_primitives() -> list[PluginRecord]:
    """Primitive actions (``PrimitiveAction``), e.g. ``PluginRecord("weigh", Weigh)``."""


@hookspec
def muble_register_sensors() -> list[PluginRecord]:
    """Sensors (``Sensor``), e.g. ``PluginRecord("wrist_ft", WristForceTorque)``."""


@hookspec
def muble_register_tasks() -> list[PluginRecord]:
    """Task template families (``Task``), e.g. ``PluginRecord("stack", StackTask)``."""


@hookspec
def muble_register_object_sets() -> list[PluginRecord]:
    """Object catalogues (``ObjectSet``), e.g. ``PluginRecord("shopvrb2", ShopVrb2Objects)``."""


@hookspec
def muble_register_agents() -> list[PluginRecord]:
    """Agents (``Agent``), e.g. ``PluginRecord("oracle", OracleAgent)``."""


@hookspec
def muble_register_trainers() -> list[PluginRecord]:
    """Trainers of learned parts (``Trainer``) for ``muble train``, e.g. ``PluginRecord("planner", PlannerTrainer)``."""


@hookspec
def muble_register_disturbances() -> list[PluginRecord]:
    """Disturbances (``muble.core.interfaces.Disturbance``): physical events during an episode, e.g.
    ``PluginRecord("slip", Slip, config=SlipConfig, takes_config=True)``."""


@hookspec
def muble_register_properties() -> list:
    """Hidden physical properties (``muble.Property`` records, returned as they are), e.g.
    ``Property("temperature", "feel", truth=..., superlatives=("warmest", "coldest"), ...)``: what the measuring
    primitive reports, the program steps and words that ask for it, its answer tolerance and comparison margin, its
    sampler (docs/plugins.md, "Adding a hidden property")."""


@hookspec
def muble_config_searchpath() -> list[str]:
    """Hydra search path entries holding the plugin's config yaml, e.g. ``["pkg://my_plugin.conf"]``.

    A plugin that ships ``conf/sensors/thermometer.yaml`` returns the package path of ``conf`` so that
    ``sensors=thermometer`` becomes selectable on the command line.
    """

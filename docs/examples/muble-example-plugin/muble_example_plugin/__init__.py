"""An example third-party MuBlE plugin.

It registers a sensor, ``contact_count`` (how many contacts MuJoCo reports at the current step), with
``conf/sensors/with_contacts.yaml`` so that ``muble sensors=with_contacts`` selects it from the command line; and a
primitive, ``tap``, with a task, ``touch``, that the built-in oracle solves (``muble task=touch``; see touch.py); and
an agent, ``greedy``, a rule-based reasoner for the single-object templates (``muble eval agent=greedy``, with
``conf/agent/greedy.yaml``; see agent.py); and a disturbance, ``nudge``, a short push on a resting object
(``muble eval +disturbances.enabled.nudge={}``; see nudge.py); and a hidden property, ``temperature`` (°C), with
its sampler, the primitive that measures it, ``feel`` (a thermal probe in a fingertip), and two templates, a query
(``measure_temperature_single``: "How warm is the red mug?") and a superlative (``pick_up_temperature``: "Pick up
the warmest of the mugs."), which the built-in oracle solves in scenes generated with
``generator.physical_properties=[temperature]`` (see temperature.py and temperature_templates.yaml).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import muble

TEMPLATES = Path(__file__).with_name("temperature_templates.yaml")


@dataclass
class ContactCountConfig:
    include_table: bool = True  # count contacts with the table too


class ContactCount(muble.Sensor):
    """Number of active contacts; a quick way to see that something touches something."""

    def __init__(self, config: ContactCountConfig):  # the registry's checked options (takes_config)
        self.include_table = config.include_table

    def read(self, env) -> dict:
        data, model = env.data, env.model
        count = 0
        for i in range(data.ncon):
            c = data.contact[i]
            names = (model.geom(c.geom1).name, model.geom(c.geom2).name)
            if self.include_table or not any("table" in n for n in names):
                count += 1
        return {"contact_count": count}


@muble.hookimpl
def muble_register_sensors():
    return [muble.PluginRecord("contact_count", ContactCount, "number of active MuJoCo contacts",
                               ContactCountConfig, takes_config=True)]


@muble.hookimpl
def muble_config_searchpath():
    return ["pkg://muble_example_plugin.conf"]


@muble.hookimpl
def muble_register_primitives():
    from muble_example_plugin.temperature import Feel
    from muble_example_plugin.touch import Tap

    return [muble.PluginRecord("tap", Tap, "touch an object with the open hand and rise again"),
            muble.PluginRecord("feel", Feel, "hold the grasped object: how warm it is (°C), from a fingertip probe")]


@muble.hookimpl
def muble_register_properties():
    from muble_example_plugin.temperature import TEMPERATURE

    return [TEMPERATURE]


@muble.hookimpl
def muble_register_tasks():
    from muble_example_plugin.touch import Touch, TouchConfig
    from muble_plugins.tasks import template_tasks

    return [muble.PluginRecord("touch", Touch, "touch the object the instruction names", TouchConfig,
                               takes_config=True),
            *template_tasks(TEMPLATES)]  # measure_temperature_single, pick_up_temperature


@muble.hookimpl
def muble_register_agents():
    from muble_example_plugin.agent import GreedyAgent, GreedyConfig

    return [muble.PluginRecord("greedy", GreedyAgent, "grasps, lifts and weighs the object the program's words name",
                               GreedyConfig, takes_config=True)]


@muble.hookimpl
def muble_register_disturbances():
    from muble_example_plugin.nudge import Nudge, NudgeConfig

    return [muble.PluginRecord("nudge", Nudge, "a short push on the resting object nearest the hand", NudgeConfig,
                               takes_config=True)]

"""An example third-party MuBlE plugin.

It registers one sensor, ``contact_count`` (how many contacts MuJoCo reports at the current step), and ships
``conf/sensors/with_contacts.yaml`` so that ``muble sensors=with_contacts`` selects it from the command line.
"""
from __future__ import annotations

from dataclasses import dataclass

import muble


@dataclass
class ContactCountConfig:
    include_table: bool = True  # count contacts with the table too


class ContactCount(muble.Sensor):
    """Number of active contacts; a quick way to see that something touches something."""

    def __init__(self, include_table: bool = True):
        self.include_table = include_table

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
                               ContactCountConfig)]


@muble.hookimpl
def muble_config_searchpath():
    return ["pkg://muble_example_plugin.conf"]

"""Measured physical properties: the last weight and stiffness measured per object (the readings of ``weigh`` and
``squeeze``, ``muble_plugins.primitives.measure``)."""
from __future__ import annotations

from typing import Any

from muble import Sensor


class Weight(Sensor):
    """Weights in grams, by scene id, of every object weighed so far this episode."""

    def read(self, env) -> dict[str, Any]:
        return {i: m["weight"] for i, m in env.measurements.items() if "weight" in m}


class Stiffness(Sensor):
    """Stiffness in N/m, by scene id, of every object squeezed so far this episode: the slope of jaw force against
    finger travel from the ``squeeze`` primitive's reading (force per metre one jaw penetrates the object)."""

    def read(self, env) -> dict[str, Any]:
        return {i: m["stiffness"] for i, m in env.measurements.items() if "stiffness" in m}

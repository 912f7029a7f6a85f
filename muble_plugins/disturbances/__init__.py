"""Built-in disturbances: physical events during an episode (``muble.core.disturbances``)."""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_disturbances() -> list[PluginRecord]:
    from muble_plugins.disturbances.builtin import (Bump, BumpConfig, SensorDropout, SensorDropoutConfig, Slip,
                                                    SlipConfig, Topple, ToppleConfig)

    return [
        PluginRecord("slip", Slip, "the grip loosens while a held object is lifted: it drops back and the lift fails",
                     config=SlipConfig, takes_config=True),
        PluginRecord("bump", Bump, "an object just set down on the table is knocked to another free place",
                     config=BumpConfig, takes_config=True),
        PluginRecord("topple", Topple, "the top object of a stack just made is knocked off onto the table",
                     config=ToppleConfig, takes_config=True),
        PluginRecord("sensor_dropout", SensorDropout, "a measuring primitive's reading fails once ('reading "
                     "unstable') and is forgotten", config=SensorDropoutConfig, takes_config=True),
    ]

"""Built-in object sets: the SHOP-VRB2 household objects and a YCB-like set.

Geometry is generated procedurally (trimesh) and cached on disk; nothing is downloaded.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_object_sets() -> list[PluginRecord]:
    from muble_plugins.objects.catalogue import ObjectSetConfig
    from muble_plugins.objects.shopvrb2 import ShopVrb2Objects
    from muble_plugins.objects.ycb import YcbObjects

    return [
        PluginRecord("shopvrb2", ShopVrb2Objects, "the ten SHOP-VRB2 household categories, procedural shapes",
                     ObjectSetConfig, takes_config=True),
        PluginRecord("ycb", YcbObjects, "nine YCB items at published size and mass, procedural shapes",
                     ObjectSetConfig, takes_config=True),
    ]

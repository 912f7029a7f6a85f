"""Built-in renderers: MuJoCo (fast, headless GL) and Blender (photoreal, bpy in-process).

Both are imported only when the registry asks for the records; neither imports a GL or Blender module at
import time (that happens in ``setup``). Blender is an extra: without ``bpy`` the plugin is listed, and creating it
fails with the command that installs it.
"""
from muble import PluginRecord, hookimpl


@hookimpl
def muble_register_renderers() -> list[PluginRecord]:
    from muble_plugins.renderers.blender import BlenderRendererConfig, create_blender_renderer
    from muble_plugins.renderers.mujoco import MujocoRenderer, MujocoRendererConfig

    return [
        PluginRecord("mujoco", MujocoRenderer, "MuJoCo OpenGL renderer: fast RGB, depth, segmentation",
                     MujocoRendererConfig, takes_config=True),
        PluginRecord("blender", create_blender_renderer, "Blender Cycles/EEVEE photoreal keyframes with GT passes",
                     BlenderRendererConfig, takes_config=True),
    ]

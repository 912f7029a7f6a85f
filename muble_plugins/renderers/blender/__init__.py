"""Blender renderer plugin: photoreal keyframes of MuJoCo states with depth and segmentation passes.

``bpy`` is imported inside ``setup``/``render`` only, so registering the plugin costs nothing, and the plugin is
registered whether or not ``bpy`` is installed (it is the extra ``muble[blender]``): ``create_blender_renderer``,
the registered factory, refuses with the command that installs it.
"""
from .availability import bpy_installed, require_bpy
from .config import BlenderRendererConfig
from .renderer import BlenderRenderer


def create_blender_renderer(config: BlenderRendererConfig) -> BlenderRenderer:
    """The registry's factory: a ``BlenderRenderer`` of the checked ``config``, or a ``PluginError`` naming the
    extra when bpy is missing."""
    require_bpy()
    return BlenderRenderer(config)


__all__ = ["BlenderRenderer", "BlenderRendererConfig", "bpy_installed", "create_blender_renderer", "require_bpy"]

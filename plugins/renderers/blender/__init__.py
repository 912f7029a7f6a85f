"""Blender renderer plugin: photoreal keyframes of MuJoCo states with depth and segmentation passes.

``bpy`` is imported inside ``setup``/``render`` only, so registering the plugin costs nothing.
"""
from .config import BlenderRendererConfig
from .renderer import BlenderRenderer

__all__ = ["BlenderRenderer", "BlenderRendererConfig"]

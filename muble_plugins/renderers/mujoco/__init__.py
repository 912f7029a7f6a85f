"""The MuJoCo renderer: fast headless RGB, depth and segmentation for previews, tests and occlusion checks."""
from muble_plugins.renderers.mujoco.renderer import MujocoRenderer, MujocoRendererConfig

__all__ = ["MujocoRenderer", "MujocoRendererConfig"]

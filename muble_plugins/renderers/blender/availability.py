"""Blender is an extra: ``bpy`` is installed by ``pip install "muble[blender]"``, and only some Pythons have it.

The plugin registers without ``bpy`` (``muble plugins`` lists it); creating it without ``bpy`` is a
``PluginError`` that names the extra, which the command line reports as a usage error (exit code 2).
"""
from __future__ import annotations

import importlib.util
import sys

from muble.core.errors import PluginError

INSTALL = 'pip install "muble[blender]"'
# The Pythons each bpy release is built for (PyPI): bpy 5.2 for 3.13, bpy 5.0 for 3.11, none for 3.12.
BPY_FOR_PYTHON = {(3, 13): "bpy 5.2", (3, 11): "bpy 5.0.1"}


def bpy_installed() -> bool:
    """Whether ``import bpy`` can find the module (without importing it: that loads all of Blender)."""
    try:
        return importlib.util.find_spec("bpy") is not None
    except (ImportError, ValueError):  # a finder refused it, or a stand-in without a spec sits in sys.modules
        return False


def require_bpy() -> None:
    """Raise a ``PluginError`` naming the extra to install when ``bpy`` is missing."""
    if bpy_installed():
        return
    version = sys.version_info[:2]
    python = "Python {}.{}".format(*version)
    if version in BPY_FOR_PYTHON:
        how = f"install the Blender extra: {INSTALL} (adds {BPY_FOR_PYTHON[version]} on {python})"
    else:
        how = (f"no bpy is built for {python}: use Python 3.13 or 3.11 and {INSTALL}, or render with "
               "renderer=mujoco")
    raise PluginError(f"renderer 'blender' needs Blender's Python module bpy, which is not installed; {how}")

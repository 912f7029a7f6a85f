"""A headless OpenGL context: EGL first, OSMesa as the fallback.

The backend is fixed when PyOpenGL is first imported (through ``PYOPENGL_PLATFORM``), so the choice is made
here, before anything imports it, and kept for the life of the process.
"""
from __future__ import annotations

import logging
import os

from muble import RenderError

log = logging.getLogger(__name__)
BACKENDS = ("egl", "osmesa")


def _context_class(backend: str):
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        raise RenderError(f"MUJOCO_GL='{backend}' cannot render headless here; valid MUJOCO_GL names: egl, osmesa")
    return GLContext


def make_context(width: int, height: int):
    """A current offscreen GL context of at least ``width`` x ``height``."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = [requested] if requested else list(BACKENDS)
    errors = []
    for backend in candidates:
        os.environ.setdefault("MUJOCO_GL", backend)
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
        try:
            context = _context_class(backend)(width, height)
            context.make_current()
            log.debug("OpenGL context from %s (%dx%d)", backend, width, height)
            return context
        except RenderError:
            raise
        except Exception as e:  # a missing driver shows up as any of several error types
            errors.append(f"{backend}: {type(e).__name__}: {e}")
    raise RenderError(
        "no headless OpenGL context could be made (" + "; ".join(errors) + "). Set MUJOCO_GL=egl with a working "
        "EGL driver (Mesa works), or MUJOCO_GL=osmesa with libosmesa6 installed")

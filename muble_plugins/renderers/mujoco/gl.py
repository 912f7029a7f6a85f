"""A headless OpenGL context: EGL first, OSMesa as the fallback, kept for reuse once a renderer is done with it.

The backend is fixed when PyOpenGL is first imported (through ``PYOPENGL_PLATFORM``), so the choice is made
here, before anything imports it, and kept for the life of the process.

A fresh context costs far more than making one: on Mesa's software rasteriser its first frames compile the
fixed-function shader variants MuJoCo draws with (about 0.6 CPU-seconds for a robosuite scene, every episode
when each episode's renderer is closed). ``release_context`` keeps a closed renderer's context for the next
``make_context`` of the same thread, so only the process's first episode pays. Which context draws a frame does
not change its pixels.
"""
from __future__ import annotations

import atexit
import logging
import os
import threading
from contextlib import contextmanager

from muble import RenderError

log = logging.getLogger(__name__)
BACKENDS = ("egl", "osmesa")
MAX_SPARE = 2  # contexts kept per thread; more renderers than that at once are rare

_spare = threading.local()  # a context is current in one thread only, so spares are kept per thread
_all_spares: list[list] = []


def _context_class(backend: str):
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        raise RenderError(f"MUJOCO_GL='{backend}' cannot render headless here; valid MUJOCO_GL names: egl, osmesa")
    return GLContext


def _spares() -> list:
    if not hasattr(_spare, "contexts"):
        _spare.contexts = []
        _all_spares.append(_spare.contexts)
    return _spare.contexts


_exit_hook = False


def make_context(width: int, height: int):
    """A current offscreen GL context of at least ``width`` x ``height`` (a released one when there is one).

    MuJoCo draws into its own framebuffer object sized from the model, so a context's own surface size does
    not limit the image; the size is passed for backends that need one."""
    spares = _spares()
    if spares:
        context = spares.pop()
        context.make_current()
        return context
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    candidates = [requested] if requested else list(BACKENDS)
    errors = []
    for backend in candidates:
        os.environ.setdefault("MUJOCO_GL", backend)
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
        try:
            context = _context_class(backend)(width, height)
            context.make_current()
            global _exit_hook
            if not _exit_hook:  # after the backend's own exit hook, so ours runs first (atexit is LIFO)
                atexit.register(free_spares)
                _exit_hook = True
            log.debug("OpenGL context from %s (%dx%d)", backend, width, height)
            return context
        except RenderError:
            raise
        except Exception as e:  # a missing driver shows up as any of several error types
            errors.append(f"{backend}: {type(e).__name__}: {e}")
    raise RenderError(
        "no headless OpenGL context could be made (" + "; ".join(errors) + "). Set MUJOCO_GL=egl with a working "
        "EGL driver (Mesa works), or MUJOCO_GL=osmesa with libosmesa6 installed")


def release_context(context) -> None:
    """Give back a context whose MuJoCo resources are freed; it is kept for reuse or freed."""
    spares = _spares()
    if len(spares) < MAX_SPARE:
        spares.append(context)
    else:
        context.free()


def free_spares() -> None:
    """Free every kept context (at exit, so EGL does not complain about live contexts)."""
    for spares in _all_spares:
        while spares:
            try:
                spares.pop().free()
            except Exception:  # noqa: BLE001 - a context of a finished thread may already be gone
                pass


@contextmanager
def draw_into(framebuffer: int, restore):
    """Bind ``framebuffer`` (a GL framebuffer object of the current context) for drawing and reading in the block;
    ``restore()`` binds the renderer's own buffer again after it (``mjr_restoreBuffer``), whatever happens."""
    from OpenGL import GL

    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, framebuffer)
    try:
        yield
    finally:
        restore()


def read_pixels(framebuffer: int, rgb, depth=None) -> None:
    """Read ``framebuffer``'s colour (GL_RGB bytes, into ``rgb``, shape (h, w, 3)) and, if given, its depth (floats,
    into ``depth``, shape (h, w)), rows bottom up, as ``mjr_readPixels`` reads a single-sample buffer."""
    from OpenGL import GL

    h, w = rgb.shape[:2]
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, framebuffer)  # mjr_render ends by binding its own buffer
    GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE, rgb)
    if depth is not None:
        GL.glReadPixels(0, 0, w, h, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, depth)

"""Blender's own console lines (``Saved: …``, Cycles' device probing) are printed by C code on the process's
stdout, past Python's logging; they are dropped while Blender renders unless this module's logger shows debug
messages (``muble --verbose``)."""
from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import sys
from typing import Iterator

log = logging.getLogger(__name__)


def _flush_c_stdio() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


@contextlib.contextmanager
def blender_console_silenced() -> Iterator[None]:
    if log.isEnabledFor(logging.DEBUG):
        yield
        return
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # stdout is not a file (captured): nothing reaches a console
        yield
        return
    sys.stdout.flush()
    _flush_c_stdio()
    saved, devnull = os.dup(fd), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        _flush_c_stdio()
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)

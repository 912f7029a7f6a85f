"""Quiet by default: third-party messages that say nothing about a MuBlE run are dropped, the rest shown once.

robosuite logs, on every import, that it has no private macro file, no ``robosuite_models`` and no mink IK (none
of which MuBlE uses), and prints each message twice once Hydra has configured logging (its own console handler
plus the root one); PyOpenGL logs that ``OpenGL_accelerate`` is missing. ``muble --verbose`` keeps them all.

``import muble`` installs the filters, so every process that imports MuBlE is quiet before robosuite is imported:
the command line's, its spawned workers (which import MuBlE to unpickle their work) and a Gymnasium user's.
``--verbose`` sets ``MUBLE_VERBOSE=1``, which the workers inherit.
"""
from __future__ import annotations

import logging
import os

ROBOSUITE_LOGGER = "robosuite_logs"
VERBOSE_ENV = "MUBLE_VERBOSE"

# Beginnings of robosuite messages about optional parts MuBlE does not use.
IRRELEVANT_ROBOSUITE = (
    "No private macro file found",
    "It is recommended to use a private macro file",
    "To setup, run:",
    "Could not import robosuite_models",
    "Could not load the mink-based whole-body IK",
)


class DropMessages(logging.Filter):
    """Drops records whose message starts with one of ``prefixes``."""

    def __init__(self, prefixes: tuple[str, ...]):
        super().__init__()
        self.prefixes = prefixes

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith(self.prefixes)


def quiet_third_party(verbose: bool | None = None) -> None:
    """Install the filters (before robosuite or PyOpenGL is imported); ``verbose=True`` takes them out again and
    marks the environment so that child processes keep every message too. ``None``: as ``MUBLE_VERBOSE`` says."""
    robosuite = logging.getLogger(ROBOSUITE_LOGGER)
    if verbose is None:
        verbose = os.environ.get(VERBOSE_ENV, "") not in ("", "0")
    if verbose:
        os.environ[VERBOSE_ENV] = "1"
        for installed in [f for f in robosuite.filters if isinstance(f, DropMessages)]:
            robosuite.removeFilter(installed)
        robosuite.propagate = True
        logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.NOTSET)
        return
    if not any(isinstance(f, DropMessages) for f in robosuite.filters):
        robosuite.addFilter(DropMessages(IRRELEVANT_ROBOSUITE))
    # robosuite adds its own console handler; without propagation each message is printed once, by it.
    robosuite.propagate = False
    logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)

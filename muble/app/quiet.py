"""Quiet by default: third-party messages that say nothing about a MuBlE run are dropped, the rest shown once.

robosuite logs, on every import, that it has no private macro file, no ``robosuite_models`` and no mink IK (none
of which MuBlE uses), and prints each message twice once Hydra has configured logging (its own console handler
plus the root one); PyOpenGL logs that ``OpenGL_accelerate`` is missing. ``muble --verbose`` keeps them all.
"""
from __future__ import annotations

import logging

ROBOSUITE_LOGGER = "robosuite_logs"

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


def quiet_third_party(verbose: bool = False) -> None:
    """Install the filters (before robosuite or PyOpenGL is imported); ``verbose=True`` leaves logging alone."""
    if verbose:
        return
    robosuite = logging.getLogger(ROBOSUITE_LOGGER)
    if not any(isinstance(f, DropMessages) for f in robosuite.filters):
        robosuite.addFilter(DropMessages(IRRELEVANT_ROBOSUITE))
    # robosuite adds its own console handler; without propagation each message is printed once, by it.
    robosuite.propagate = False
    logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)

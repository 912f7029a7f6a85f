"""Physical measurements through the robot: weight from the wrist force sensor, stiffness from squeezing.

Both read what the simulated hardware reports (sensor forces, finger pad positions); neither looks at the ground
truth stored in the model.
"""
from __future__ import annotations

import logging

import numpy as np

from muble.core.errors import PhysicsError

logger = logging.getLogger(__name__)

GRAVITY = 9.81
WEIGH_SETTLE = 0.6  # s of holding still before reading; see docs/environment.md for how it was chosen
WEIGH_WINDOW = 0.2  # s over which the force is averaged


def mean_wrist_force(env, window: float = WEIGH_WINDOW) -> np.ndarray:
    """Wrist force (world frame) averaged over ``window`` seconds, sampled every control step while holding."""
    samples = []
    env.advance(window, on_control=lambda k: samples.append(env.wrist_wrench()[0].copy()))
    samples.append(env.wrist_wrench()[0].copy())
    return np.mean(samples, axis=0)


def weigh(env, settle: float = WEIGH_SETTLE, window: float = WEIGH_WINDOW) -> float:
    """Weight in grams of what the hand holds: hold still, read the wrist force, subtract the tare, divide by g.

    Needs a tare taken with the empty hand (``env.tare()``, before grasping).
    """
    if env.tare_force is None:
        raise PhysicsError("no tare: call env.tare() with the empty hand, before grasping, then weigh")
    env.hold(settle)
    force = mean_wrist_force(env, window)
    # Sign measured: a held load adds +z to the world-frame reading of this sensor.
    extra = force - env.tare_force
    grams = float(extra[2] / GRAVITY * 1000.0)
    if env.held_object is not None:
        env.measurements.setdefault(env.held_object, {})["weight"] = grams
    return grams

"""Whether an object stayed: settled where a scene put it, at rest, upright, not leaning over after a put-down,
and the height it comes to rest at.

One home for what the initial-state check and the scene generator's rest check demand of a scene before anything
acts, what ``lower`` checks after letting go, what the tasks' judges and planners read from a scene, and what the
scene generator's stack check simulates. Tilt is ``muble.stage.geometry.tilt_deg``. The limits, decided on purpose:

- ``SETTLED_DISPLACEMENT`` (5 mm) and ``SETTLED_TURN`` (3 degrees): how far an object's origin or centre of mass
  may move, and how far it may turn, while its scene settles, for it still to stand where the scene put it
  (docs/environment.md, "Initial state", gives the figures they were measured against).
- ``RESTING_SPEED`` (0.01 m/s): a body's linear speed below which it is at rest. A put-down waits for it, and a
  judge counts an object moving faster as not resting: 1 cm/s is a visible slide or roll, and a settled object
  in MuJoCo moves at well under a millimetre a second.
- ``UPRIGHT_DEG`` (20 degrees): the most an object's axis may lean from the vertical and still stand upright
  (a mug on a bowl's curved floor leans a little; a fallen can leans 90).
- ``LEAN_DEG`` (20 degrees, the same): the most a put-down object may lean *further* than when it was let go,
  so one let go upright ends upright, and one let go tilted (a plate set into a tray) is not failed for its tilt.
- ``STACK_LEAN_DEG`` (15 degrees, three quarters of ``LEAN_DEG``): the margin the scene generator demands of a
  stack in its physics check, so that a put-down a little off centre, as the arm makes it, still ends within
  ``LEAN_DEG``.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from muble.stage.geometry import tilt_deg

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

SETTLED_DISPLACEMENT = 0.005  # m
SETTLED_TURN = 3.0  # degrees
RESTING_SPEED = 0.01  # m/s
UPRIGHT_DEG = 20.0  # degrees from the vertical
LEAN_DEG = UPRIGHT_DEG  # degrees further than when let go
STACK_LEAN_DEG = 0.75 * LEAN_DEG  # degrees: the generator's margin


def settled(displacement: float, turn: float = 0.0, limit: float = SETTLED_DISPLACEMENT) -> bool:
    """An object that moved ``displacement`` (m: its origin or centre of mass, whichever moved more) and turned
    ``turn`` degrees while its scene settled stands where the scene put it (``limit``: the displacement allowed)."""
    return float(displacement) <= limit and float(turn) <= SETTLED_TURN


def at_rest(speed: float) -> bool:
    """A body moving at ``speed`` (m/s, linear) is at rest."""
    return float(speed) < RESTING_SPEED


def _tilt(quat_or_tilt) -> float:
    return float(quat_or_tilt) if isinstance(quat_or_tilt, (int, float)) else tilt_deg(quat_or_tilt)


def upright(quat) -> bool:
    """A body turned by ``quat`` (w, x, y, z; or its tilt in degrees) stands upright."""
    return _tilt(quat) <= UPRIGHT_DEG


def leaned_over(quat, quat_at_release, limit: float = LEAN_DEG) -> float | None:
    """Degrees a body turned by ``quat`` leans further than it did when let go (``quat_at_release``, or a tilt in
    degrees), when that is more than ``limit``; else None."""
    lean = tilt_deg(quat) - _tilt(quat_at_release)
    return lean if lean > limit else None


def resting_height(model: "mujoco.MjModel", data: "mujoco.MjData", support_body: int, points_xy: np.ndarray,
                   start_z: float, skip_body: int, geom_groups: np.ndarray | None = None) -> float | None:
    """The height at which something with the footprint ``points_xy`` (world x, y) comes to rest on
    ``support_body``: the highest point of the support under those points, found by rays straight down from
    ``start_z`` that pass through ``skip_body`` (the held object itself). Rays see the geoms of ``geom_groups``
    (MuJoCo's six-group mask; None: all). None where no ray meets the support (nothing of it under the
    footprint). The inner floor of a bowl a can fits into, the rim of one a wider object spans."""
    import mujoco

    groups = np.ones(6, dtype=np.uint8) if geom_groups is None else geom_groups
    hit = np.zeros(1, dtype=np.int32)
    down = np.array([0.0, 0.0, -1.0])
    heights = []
    for x, y in points_xy:
        dist = mujoco.mj_ray(model, data, np.array([x, y, start_z]), down, groups, 0, skip_body, hit)
        if dist >= 0 and model.geom_bodyid[hit[0]] == support_body:
            heights.append(start_z - dist)
    return float(max(heights)) if heights else None

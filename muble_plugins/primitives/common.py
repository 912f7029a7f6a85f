"""What several arm-motion primitives share: the typed parameters, retries by ``attempt``, the checked result,
and the ways a carried object may be turned and let go (``move`` goes over the place ``lower`` then uses)."""
from __future__ import annotations

import numpy as np

from muble import ActionResult, Param
from muble_plugins.primitives import context as ctx

# ``attempt`` values a retrying agent may pass (0 to 16): it starts from the attempt-th best option, and
# ``rotated`` wraps round where a primitive has fewer options.
MAX_ATTEMPT = 16

# Typed parameters: the action loop rejects other calls as invalid actions before anything runs.
TARGET_PLACE = Param("target", "place", required=True, doc="object id or table part")
ATTEMPT = Param("attempt", "int", low=0, high=MAX_ATTEMPT, default=0,
                doc="retry number: start from the attempt-th best option (grasp, place, hover pose)")


def rotated(options: list, attempt: int) -> list:
    """``options`` with the ``attempt``-th first: a retry tries the alternatives before the option that failed."""
    if not options:
        return options
    k = int(attempt) % len(options)
    return list(options[k:]) + list(options[:k])


# rad any arm joint may end from the planned final configuration for the motion to count: about 3 deg, far more
# than a free arm lags at the end of a settled move, so a larger error means it was blocked or overloaded.
END_TRACKING = 0.05


def checked_result(report: ctx.MotionReport, env=None, held: int | None = None, **info) -> ActionResult:
    """The motion's result, checked: the arm ended where it was sent (``END_TRACKING``), and it still holds what
    it held."""
    info.update(unintended_contacts=sorted(report.unintended_contacts), duration=report.duration,
                final_error=report.final_error)
    if np.isfinite(report.final_error) and report.final_error > END_TRACKING:
        return ActionResult(False, info=info, failure_reason=f"the arm ended {report.final_error:.3f} rad from the "
                                                            f"planned configuration (blocked or overloaded)")
    if env is not None and held is not None and env.held_object != held:
        return ActionResult(False, info=info, failure_reason=f"object {held} slipped out of the hand while moving")
    return ActionResult(True, info=info)


# rad about the vertical that the hand may turn a carried object (the object turning with it), tried in this
# order: as lifted first, then eighths of a turn either way, growing to a half turn.
# ``move`` tries them to reach over a target near the workspace edge, ``lower`` to fit down onto an object.
CARRY_TURNS = tuple(np.radians([0, 45, -45, 90, -90, 135, -135, 180]))

# m between the held object's bottom and its support at the moment it is let go, tried in this order: 4 mm, a
# drop too short to disturb it, then, where a neighbour blocks the last centimetres of the descent (fingers
# beside a tall object), 15 mm and 30 mm: a short drop still lands it; last 50 and 70 mm, for a bowl held by its
# rim and set into a wider bowl, whose outer finger meets the base's wall 3 to 4 cm above where the held bowl would
# rest (nested, it lands centred from there). ``move`` goes over a place for the first.
RELEASE_GAPS = (0.004, 0.015, 0.03, 0.05, 0.07)

# Gripper command (-1 open, 1 closed) of the hand opened part way: still wide enough for a rim or a handle,
# narrower than the open hand where that touches a neighbour or would reach across a rim.
PART_OPEN = 0.0


# m between the pads holding an object below which the hold counts as a thin part (a rim, a handle, a stem) and
# it is let go with the hand part open.
THIN_HOLD = 0.025


def release_command(env) -> float:
    """The gripper command that lets the held object go: fully open (-1), or for a thin part held (a rim, a
    handle, a stem; under ``THIN_HOLD``) only part way: opened fully, the finger inside a rim would reach across
    to the far side and catch it on the way up."""
    return PART_OPEN if ctx.pad_gap(env) < THIN_HOLD else -1.0

"""Arm motion primitives: move above a target, approach for grasping, lift, lower (put down), move_vel.

One module each (``move``, ``approach``, ``lift``, ``lower``, ``move_vel``; what several share is in ``common``);
this module gathers the classes. Each plans completely before it moves where it can, so a ``PlanningError`` leaves
the environment as it was; a primitive that fails after moving restores the snapshot taken at its start before
re-raising.
"""
from muble_plugins.primitives.approach import Approach
from muble_plugins.primitives.lift import Lift
from muble_plugins.primitives.lower import Lower
from muble_plugins.primitives.move import Move
from muble_plugins.primitives.move_vel import MoveVel

__all__ = ["Approach", "Lift", "Lower", "Move", "MoveVel"]

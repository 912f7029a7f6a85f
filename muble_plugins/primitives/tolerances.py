"""How closely the built-in primitives reach their poses and how long they let the physics settle.

The other numbers that govern grasping, placing and retreating live beside the code they steer, each with its
reason (``common.RELEASE_GAPS``, ``common.THIN_HOLD``, ``context.HOVER``, ``lower.RETREAT`` …); docs/planning.md
tables them all.
"""
from __future__ import annotations

# Pose goals: (position m, orientation rad) within which the planned end pose counts as reached.
FREE = (0.005, 0.05)  # hovering over a target, rising, lifting, retreating: free space, nothing to meet
CONTACT = (0.004, 0.05)  # the last centimetres into a grasp or down onto a place, where millimetres matter
VELOCITY = (0.003, 0.05)  # ``move_vel``'s end pose, which it then checks against MOVE_VEL_TOLERANCE

# Seconds the arm holds still so the simulation settles before the next step reads it.
SETTLE = 0.3  # after a planned motion, after the open hand's fingers move, before a put-down object is judged
RELEASE_SETTLE = 0.5  # after the fingers open round a put-down object, before the hand moves away from it
STEP_SETTLE = 0.2  # between small corrective moves (following a released object) and extra finger closing
REST_CHECK = 0.25  # between two looks at a put-down object's speed while waiting for it to rest

"""The hand's state as a scene graph records it, and what the primitives' symbolic effects share.

A world keeps the gripper's state in flags of ``SceneObject.extra`` (``FLAGS``): the object in the hand
(``in_hand``), raised off its support (``raised``), approached in its grasp pose (``approached``), under the
hovering gripper (``gripper_over``); the physical world reports the same flags. A primitive's
``PrimitiveAction.symbolic_effect`` reads them with ``ArmState.of`` and sets them with ``set_flag``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from muble.core.scene import SceneGraph, SceneObject

FLAGS = ("in_hand", "raised", "approached", "gripper_over")
RAISE_HEIGHT = 0.1  # metres a raised object stands above its resting pose in the symbolic world
ARRIVAL_TOLERANCE = 0.03  # metres between a carried object and its destination that count as arrived over it
# Key of ``SceneObject.extra`` (ground truth only) for the table point a raised object was carried over by a
# move to a table part; putting the object down uses it and removes it.
CARRIED_TO = "carried_to"


def over(held: SceneObject, base: SceneObject) -> bool:
    """``held`` is within ``ARRIVAL_TOLERANCE`` of ``base`` about the vertical (carried over it, or standing on
    it)."""
    return math.hypot(held.position[0] - base.position[0], held.position[1] - base.position[1]) <= ARRIVAL_TOLERANCE


@dataclass
class ArmState:
    """The gripper's symbolic state read from a scene graph."""

    held: int | None
    raised: bool
    approached: int | None
    over: int | None

    @classmethod
    def of(cls, scene: SceneGraph) -> "ArmState":
        held = approached = over = None
        raised = False
        for o in scene.objects:
            if o.extra.get("in_hand"):
                held, raised = o.id, bool(o.extra.get("raised"))
            if o.extra.get("approached"):
                approached = o.id
            if o.extra.get("gripper_over"):
                over = o.id
        return cls(held, raised, approached, over)

    def held_object(self, scene: SceneGraph) -> SceneObject | None:
        return scene.object(self.held) if self.held is not None else None


def set_flag(scene: SceneGraph, flag: str, obj: SceneObject | None) -> None:
    """``flag`` on ``obj`` alone (None: on no object)."""
    for o in scene.objects:
        o.extra[flag] = o is obj

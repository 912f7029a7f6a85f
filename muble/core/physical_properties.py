"""The hidden physical properties besides weight and stiffness: friction, centre of mass and loose contents.

A scene object carries their ground truth in ``SceneObject.extra`` under the keys below; an agent never sees
them (the agent view is an allow-list, ``muble.core.observation``). ``muble.sim.build.object_models`` builds them
into the object's ``ObjectModel``; without them the object is simulated exactly as before. The measuring primitives
(``push``, ``balance``, ``shake``) record what they measured in ``Environment.measurements`` (``friction``, the
centre of mass's ``com_offset`` [x, y] in mm, ``rattles``). See docs/physical_properties.md.
"""
from __future__ import annotations

import math
from typing import Any

from muble.core.errors import SceneValidationError
from muble.core.scene import SceneObject

FRICTION = "friction_coefficient"  # the object's own Coulomb friction coefficient (no unit)
COM_OFFSET = "com_offset"  # [x, y] or [x, y, z] m, object frame: the centre of mass off the geometric centre
CONTENTS = "contents_g"  # grams of loose contents in a closed container (part of ``weight_gt``)


def friction_of(obj: SceneObject) -> float | None:
    """The object's ground-truth friction coefficient, or None when its scene gives none."""
    value = obj.extra.get(FRICTION)
    return None if value is None else float(value)


def com_offset_mm(obj: SceneObject) -> list[float] | None:
    """The ground truth of a ``balance`` reading: the centre of mass's horizontal offset [x, y] (mm, object frame)
    from the object's origin, or None when its scene gives no centre of mass."""
    value = obj.extra.get(COM_OFFSET)
    return None if value is None else [float(value[0]) * 1000.0, float(value[1]) * 1000.0]


def rattles(obj: SceneObject) -> bool:
    """Whether the object holds loose contents (a ``shake`` reading's ground truth)."""
    return float(obj.extra.get(CONTENTS) or 0.0) > 0.0


def checked(obj: SceneObject) -> dict[str, Any]:
    """The object's properties as ``ObjectModel`` fields (``friction_coefficient``, ``com_offset`` in m,
    ``contents_mass`` in kg), only those its scene gives; a value that is not physical is a
    ``SceneValidationError`` naming the object and the key."""
    out: dict[str, Any] = {}
    if obj.extra.get(FRICTION) is not None:
        mu = _number(obj, FRICTION, obj.extra[FRICTION])
        if not mu > 0:
            raise SceneValidationError(f"must be a positive friction coefficient, got {mu}", obj=obj.id,
                                       field=FRICTION)
        out["friction_coefficient"] = mu
    if obj.extra.get(COM_OFFSET) is not None:
        value = obj.extra[COM_OFFSET]
        if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
            raise SceneValidationError(f"must be [x, y] or [x, y, z] in metres, got {value!r:.60}", obj=obj.id,
                                       field=COM_OFFSET)
        out["com_offset"] = [_number(obj, COM_OFFSET, v) for v in value]
    if obj.extra.get(CONTENTS) is not None:
        grams = _number(obj, CONTENTS, obj.extra[CONTENTS])
        if grams < 0 or (obj.weight_gt is not None and grams >= float(obj.weight_gt)):
            raise SceneValidationError(f"must be at least 0 g and less than the weight ({obj.weight_gt} g), got "
                                       f"{grams}", obj=obj.id, field=CONTENTS)
        if grams > 0:
            out["contents_mass"] = grams / 1000.0
    return out


def _number(obj: SceneObject, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise SceneValidationError(f"must hold finite numbers, got {value!r:.40}", obj=obj.id, field=key)
    return float(value)

"""The hidden physical properties besides weight and stiffness: friction, centre of mass and loose contents.

A scene object carries their ground truth in ``SceneObject.extra`` under the keys below; an agent never sees
them (the agent view is an allow-list, ``muble.core.observation``). ``muble.sim.build.object_models`` builds them
into the object's ``ObjectModel``; without them the object is simulated exactly as before. The measuring primitives
(``push``, ``balance``, ``shake``) record what they measured in ``Environment.measurements`` (``friction``, the
centre of mass's ``com_offset`` [x, y] in mm, ``rattles``). See docs/physical_properties.md.

The scene generator draws them (``sampled``, from the ranges below) for the objects an object set says carry them
(``ObjectSet.physical_properties``) when its ``physical_properties`` option names them (docs/scene_generation.md).
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from muble.core.errors import SceneValidationError
from muble.core.scene import SceneObject

FRICTION = "friction_coefficient"  # the object's own Coulomb friction coefficient (no unit)
COM_OFFSET = "com_offset"  # [x, y] or [x, y, z] m, object frame: the centre of mass off the geometric centre
CONTENTS = "contents_g"  # grams of loose contents in a closed container (part of ``weight_gt``)

# The properties the scene generator draws (``GeneratorConfig.physical_properties``; which objects carry which:
# ``ObjectSet.physical_properties``) and the scene key each is written under.
PROPERTIES = ("friction", "com_offset", "contents")
SCENE_KEYS = {"friction": FRICTION, "com_offset": COM_OFFSET, "contents": CONTENTS}

# The ranges they are drawn from; benchmarks/physical_properties.py measures how well they are read across them.
FRICTION_RANGE = (0.3, 1.0)  # uniform
COM_RADIUS_SHARE = 0.3  # of the smaller horizontal extent: 0.6 of the way from the centre to the nearest side
CONTENTS_PROBABILITY = 0.5  # of a closed container holding loose contents: a shake has two answers to tell apart
CONTENTS_G = (10.0, 40.0)  # uniform
CONTENTS_SHARE = 0.2  # the contents weigh at most this share of the object, so the container keeps most of it


def sampled(name: str, rng: np.random.Generator, model: Any, weight_g: float) -> float | list[float]:
    """A value of property ``name`` (one of ``PROPERTIES``) for the object built as ``model`` (an ``ObjectModel``)
    weighing ``weight_g`` grams, drawn from ``rng`` and rounded as the scene file keeps it under
    ``SCENE_KEYS[name]``:

    - ``friction``: a coefficient uniform in ``FRICTION_RANGE``, 3 decimals (one draw);
    - ``com_offset``: [x, y] m, uniform over the disc of radius ``COM_RADIUS_SHARE`` of the smaller horizontal
      extent about the base centre, 4 decimals (two draws: the angle, then the radius);
    - ``contents``: grams, 0.1 g: with ``CONTENTS_PROBABILITY`` uniform in ``CONTENTS_G`` and at most
      ``CONTENTS_SHARE`` of the weight, else 0.0, a container known to be empty (one draw, two with contents).
      Only a closed container (``ObjectModel.closed``) holds contents: another is a ``ValueError``.
    """
    if name == "friction":
        return round(float(rng.uniform(*FRICTION_RANGE)), 3)
    if name == "com_offset":
        radius = COM_RADIUS_SHARE * float(min(model.extents[:2]))
        angle, r = float(rng.uniform(0.0, 2.0 * math.pi)), radius * math.sqrt(float(rng.uniform()))
        return [round(r * math.cos(angle), 4) + 0.0, round(r * math.sin(angle), 4) + 0.0]  # + 0.0: no "-0.0"
    if name == "contents":
        if not model.closed:
            raise ValueError(f"a {model.spec.category} is no closed container: it cannot hold loose contents")
        if float(rng.uniform()) >= CONTENTS_PROBABILITY:
            return 0.0
        return round(min(float(rng.uniform(*CONTENTS_G)), CONTENTS_SHARE * float(weight_g)), 1)
    raise ValueError(f"unknown physical property '{name}'; valid physical property names: {', '.join(PROPERTIES)}")


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
    return model_fields(obj.extra, obj.weight_gt, obj.id)


def model_fields(extra: Mapping[str, Any], weight_g: float | None, obj_id: int | None = None) -> dict[str, Any]:
    """``checked`` of an object whose ``extra`` and ``weight_gt`` are these (``obj_id`` names it in errors)."""
    out: dict[str, Any] = {}
    if extra.get(FRICTION) is not None:
        mu = _number(obj_id, FRICTION, extra[FRICTION])
        if not mu > 0:
            raise SceneValidationError(f"must be a positive friction coefficient, got {mu}", obj=obj_id,
                                       field=FRICTION)
        out["friction_coefficient"] = mu
    if extra.get(COM_OFFSET) is not None:
        value = extra[COM_OFFSET]
        if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
            raise SceneValidationError(f"must be [x, y] or [x, y, z] in metres, got {value!r:.60}", obj=obj_id,
                                       field=COM_OFFSET)
        out["com_offset"] = [_number(obj_id, COM_OFFSET, v) for v in value]
    if extra.get(CONTENTS) is not None:
        grams = _number(obj_id, CONTENTS, extra[CONTENTS])
        if grams < 0 or (weight_g is not None and grams >= float(weight_g)):
            raise SceneValidationError(f"must be at least 0 g and less than the weight ({weight_g} g), got "
                                       f"{grams}", obj=obj_id, field=CONTENTS)
        if grams > 0:
            out["contents_mass"] = grams / 1000.0
    return out


def _number(obj_id: int | None, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise SceneValidationError(f"must hold finite numbers, got {value!r:.40}", obj=obj_id, field=key)
    return float(value)

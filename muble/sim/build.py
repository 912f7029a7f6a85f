"""Building an environment from a scene graph and an object set (plugin) by name or instance.

Physical properties are checked on the way: a scene object's ``weight_gt`` (the body mass, g) must be a positive
finite number and its ``stiffness`` (N/m) too, or missing; a missing stiffness takes the object set's default for
the object's material (``ObjectSet.default_stiffness``), logged once per object set and material. The built
model's mass and inertia are checked as well. The hidden properties a scene object's ``extra`` may give (friction
coefficient, centre of mass, loose contents: ``muble.core.physical_properties``) are checked and built into its
model. Anything else is a ``SceneValidationError`` naming the object and the field; nothing becomes 0.
"""
from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any

import numpy as np

from muble.core import physical_properties
from muble.core.errors import SceneValidationError
from muble.core.objects import ObjectModel, ObjectSpec
from muble.core.scene import SceneGraph, SceneObject

log = logging.getLogger(__name__)

_defaults_logged: set[tuple[str, str, float]] = set()


def _positive_number(value: Any, obj: SceneObject, field: str, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneValidationError(f"must be a number ({unit}), got {type(value).__name__} {value!r:.40}",
                                   obj=obj.id, field=field)
    number = float(value)
    if not math.isfinite(number) or number <= 0:
        raise SceneValidationError(f"must be a positive finite number ({unit}), got {number}", obj=obj.id,
                                   field=field)
    return number


def stiffness_of(obj: SceneObject, object_set: Any, set_name: str = "") -> float:
    """The object's contact stiffness (N/m): its own, or the object set's default for its material."""
    if obj.stiffness is not None:
        return _positive_number(obj.stiffness, obj, "stiffness", "N/m")
    supply = getattr(object_set, "default_stiffness", None)
    default = supply(obj.material) if supply is not None else None
    if default is None:
        raise SceneValidationError(
            f"is missing and object set '{set_name}' has no default stiffness for material '{obj.material}'; "
            "give the object a stiffness (N/m) or a material the object set knows", obj=obj.id, field="stiffness")
    default = float(default)
    if not math.isfinite(default) or default <= 0:
        raise SceneValidationError(f"object set '{set_name}' gives the invalid default {default} for material "
                                   f"'{obj.material}'", obj=obj.id, field="stiffness")
    key = (set_name, obj.material, default)
    if key not in _defaults_logged:
        _defaults_logged.add(key)
        log.warning("scene objects without a stiffness take the %s default for %s: %.1f N/m (first: object %d)",
                    set_name or "object set", obj.material, default, obj.id)
    return default


def spec_from_scene_object(obj: SceneObject, object_set: str) -> ObjectSpec:
    """The ``ObjectSpec`` a scene object was sampled from, rebuilt from the fields the scene file keeps.

    An object set may override this with a method of the same name (e.g. to restore extra geometry
    parameters it stored in ``obj.extra["params"]``). ``object_models`` fills in a missing stiffness first.
    """
    if obj.stiffness is None:
        raise SceneValidationError("is missing; object_models() fills it from the object set's material default",
                                   obj=obj.id, field="stiffness")
    return ObjectSpec(
        object_set=object_set, category=obj.name, model=obj.model, colour=obj.colour, material=obj.material,
        size=obj.size, shape=obj.shape, scale=float(obj.scale_factor or 1.0), weight_g=float(obj.weight_gt),
        stiffness=float(obj.stiffness), friction=float(obj.extra.get("friction", 1.0)),
        params=dict(obj.extra.get("params", {})),
    )


def check_model(obj_id: int, model: ObjectModel) -> None:
    """Raise ``SceneValidationError`` if a built model's mass, inertia or stiffness is not physical."""
    mass = float(model.mass)
    if not math.isfinite(mass) or mass <= 0:
        raise SceneValidationError(f"the built model's mass is {mass} kg", obj=obj_id, field="weight_gt")
    inertia = np.asarray(model.inertia, dtype=float)
    if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)) or not np.allclose(inertia, inertia.T):
        raise SceneValidationError(f"the built model's inertia is not a finite symmetric 3x3 tensor: "
                                   f"{inertia.tolist()}", obj=obj_id, field="inertia")
    moments = np.sort(np.linalg.eigvalsh(inertia))
    # Principal moments of a real body are positive and obey the triangle inequality (a + b >= c).
    if moments[0] <= 0 or moments[0] + moments[1] < moments[2] * (1 - 1e-6):
        raise SceneValidationError(f"the built model's principal moments of inertia {moments.tolist()} kg·m² are "
                                   "not those of a physical body", obj=obj_id, field="inertia")
    stiffness = float(model.stiffness)
    if not math.isfinite(stiffness) or stiffness <= 0:
        raise SceneValidationError(f"the built model's stiffness is {stiffness} N/m", obj=obj_id, field="stiffness")


def with_physical_properties(obj: SceneObject, model: ObjectModel) -> ObjectModel:
    """``model`` with the friction, centre of mass and loose contents the scene object's ``extra`` gives
    (``muble.core.physical_properties``); the model itself where it gives none. Loose contents need a closed
    container (``ObjectModel.closed``)."""
    properties = physical_properties.checked(obj)
    if not properties:
        return model
    if properties.get("contents_mass") and not model.closed:
        raise SceneValidationError(f"a {obj.name} is no closed container: it cannot hold loose contents", obj=obj.id,
                                   field=physical_properties.CONTENTS)
    return dataclasses.replace(model, **properties)


def object_models(scene: SceneGraph, object_set: Any, set_name: str = "") -> dict[int, ObjectModel]:
    """One built ``ObjectModel`` per scene object, after checking each object's mass and stiffness."""
    to_spec = getattr(object_set, "spec_from_scene_object", None)
    label = set_name or getattr(object_set, "set_name", "") or type(object_set).__name__
    models = {}
    for obj in scene.objects:
        _positive_number(obj.weight_gt, obj, "weight_gt", "grams")
        stiffness = stiffness_of(obj, object_set, label)
        if obj.stiffness is None:
            obj = dataclasses.replace(obj, stiffness=stiffness)
        spec = to_spec(obj) if to_spec is not None else spec_from_scene_object(obj, set_name)
        models[obj.id] = with_physical_properties(obj, object_set.build(spec))
        check_model(obj.id, models[obj.id])
    return models


def env_from_object_set(scene: SceneGraph, object_set: Any, robot: Any = None,
                        sensors: list[str] | tuple[str, ...] = (), **overrides: Any):
    """A ``TabletopEnv`` for ``scene`` whose objects come from ``object_set`` (an ``ObjectSet`` or its registry
    name) and whose sensors are the named sensor plugins."""
    from muble.plugins.registry import get_registry
    from muble.sim.env import TabletopEnv

    registry = get_registry()
    name = object_set if isinstance(object_set, str) else getattr(object_set, "name", type(object_set).__name__)
    if isinstance(object_set, str):
        object_set = registry.create("object_set", object_set)
    built = {s: registry.create("sensor", s) for s in sensors}
    return TabletopEnv(scene, object_models(scene, object_set, name), robot, built, **overrides)

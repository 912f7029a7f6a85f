"""Building an environment from a scene graph and an object set (plugin) by name or instance."""
from __future__ import annotations

from typing import Any

from muble.core.objects import ObjectModel, ObjectSpec
from muble.core.scene import SceneGraph, SceneObject


def spec_from_scene_object(obj: SceneObject, object_set: str) -> ObjectSpec:
    """The ``ObjectSpec`` a scene object was sampled from, rebuilt from the fields the scene file keeps.

    An object set may override this with a method of the same name (e.g. to restore extra geometry
    parameters it stored in ``obj.extra["params"]``).
    """
    return ObjectSpec(
        object_set=object_set, category=obj.name, model=obj.model, colour=obj.colour, material=obj.material,
        size=obj.size, shape=obj.shape, scale=float(obj.scale_factor or 1.0), weight_g=float(obj.weight_gt),
        stiffness=float(obj.stiffness if obj.stiffness is not None else 0.0),
        friction=float(obj.extra.get("friction", 1.0)), params=dict(obj.extra.get("params", {})),
    )


def object_models(scene: SceneGraph, object_set: Any, set_name: str = "") -> dict[int, ObjectModel]:
    """One built ``ObjectModel`` per scene object."""
    to_spec = getattr(object_set, "spec_from_scene_object", None)
    models = {}
    for obj in scene.objects:
        spec = to_spec(obj) if to_spec is not None else spec_from_scene_object(obj, set_name)
        models[obj.id] = object_set.build(spec)
    return models


def env_from_object_set(scene: SceneGraph, object_set: Any = "shopvrb2", robot: Any = None,
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

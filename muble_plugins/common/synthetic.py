"""Symbolic scenes of a registered object set, for training data, generator statistics and tests.

No physics: objects get what the object set draws for them (``ObjectSet.sample``: category, model, colour,
material, size word and scale, weight, stiffness) and what its models say of them (``ObjectSet.build``: extents,
stackable, stack_base, pickupable, closed), a spot on the table, and with ``properties_rng`` the hidden physical
properties (``muble.core.physical_properties``) the set says each object carries, drawn as the scene generator
draws them. That is all instruction generation and symbolic planning read, and it is what ``muble generate`` puts in
a scene file, so a model trained on these scenes sees the benchmark's objects: there is no second catalogue here.
The object set defaults to SHOP-VRB2's (``shopvrb2``) through the registry; ``object_set(protocol)`` gives a
protocol's training pool. Building a model costs a dictionary look-up once its (model, scale) geometry is in the
set's in-memory cache (``muble_plugins.objects.build_cache``), so thousands of scenes cost seconds.

The spots come from the scene generator's layout sampler (``muble.stage.layout``) on the stage's reach area, with
the models' extents as the objects' footprints.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from muble.core import physical_properties, streams
from muble.core.errors import ConfigError

from muble import ObjectSet, SceneGraph, SceneObject, get_registry
from muble.stage.layout import BoxShape, TableLayout
from muble.stage.table import STAGES, UNNAMED_STAGE

# A synthetic scene's streams (muble.core.streams), each keyed by the caller's seed and scene key: the hidden
# properties apart from the rest, so that drawing them changes nothing else a scene holds.
SCENE_STREAM = streams.declare("synthetic.scene", "a synthetic symbolic scene's object count, objects (the object "
                               "set's draws: attributes, weights, stiffnesses) and placements "
                               "(muble_plugins.common.synthetic; the caller's scene key)")
PROPERTIES_STREAM = streams.declare("synthetic.properties", "a synthetic scene's hidden physical properties (the "
                                    "caller's scene key)")
PLACE_TRIES = 20  # poses tried per object before another object is drawn in its stead
# Objects drawn in a row that find no room before the scene starts over (the scene generator too draws a whole new
# scene when a layout fails): a table that big boards and trays have filled may have room for nothing more.
REDRAWS = 100
RESTARTS = 20
DEFAULT_OBJECT_SET = "shopvrb2"

_OBJECT_SETS: dict[str, ObjectSet] = {}


def object_set(protocol: dict | None = None, name: str = DEFAULT_OBJECT_SET) -> ObjectSet:
    """The registered object set ``name`` as ``muble generate`` samples it: with a protocol, its training split's
    pool (the protocol's common object options and its ``train`` split's), so that no held-out model, finish or
    property range of an evaluation split is drawn. One instance per set and options in a process (its geometry
    cache is what keeps the scenes cheap)."""
    params: dict[str, Any] = {}
    if protocol and name != DEFAULT_OBJECT_SET:
        raise ConfigError(f"object set {name!r} with a protocol: a protocol's pools are SHOP-VRB2 objects; "
                          f"train without protocol=... for the {name!r} set")
    if protocol:
        train = ((protocol.get("splits") or {}).get("train") or {}).get("objects") or {}
        for key, value in {**((protocol.get("common") or {}).get("objects") or {}), **train}.items():
            params[key] = value
    key = json.dumps([name, params], sort_keys=True, default=str)
    if key not in _OBJECT_SETS:
        _OBJECT_SETS[key] = get_registry().create("object_set", name, params)
    return _OBJECT_SETS[key]


def _placed_objects(rng: np.random.Generator, n_objects: tuple[int, int], objects: ObjectSet):
    """(specs, models, scene objects) of a drawn count of objects placed on the table, or ``None`` when
    ``REDRAWS`` objects in a row found no room."""
    n = int(rng.integers(n_objects[0], n_objects[1] + 1))
    layout = TableLayout.on_stage(STAGES[UNNAMED_STAGE])
    specs: list = []
    models: list = []
    scene_objects: list[SceneObject] = []
    failed = 0
    while len(scene_objects) < n:
        spec = objects.sample(rng)
        model = objects.build(spec)
        ex, ey, ez = (float(e) for e in model.extents)
        placement = layout.try_place(BoxShape(ex, ey), rng, PLACE_TRIES)
        if placement is None:
            failed += 1
            if failed >= REDRAWS:
                return None
            continue  # no room for this one: draw another
        failed = 0
        specs.append(spec)
        models.append(model)
        scene_objects.append(SceneObject(
            id=len(scene_objects), model=spec.model, name=spec.category, shape=spec.shape, size=spec.size,
            material=spec.material, colour=spec.colour, position=placement.position, orientation=placement.quat,
            weight_gt=round(float(spec.weight_g), 1), stiffness=spec.stiffness, stackable=bool(model.stackable),
            stack_base=bool(model.stack_base), pickupable=bool(model.pickupable),
            movability="portable" if model.pickupable else "stationary", scale_factor=float(spec.scale),
            rotation=math.degrees(placement.yaw), bbox={"x": ex, "y": ey, "z": ez},
        ))
    return specs, models, scene_objects


def sample_scene(rng: np.random.Generator, index: int = 0, n_objects: tuple[int, int] = (3, 6),
                 properties_rng: np.random.Generator | None = None,
                 objects: ObjectSet | None = None) -> SceneGraph:
    """A scene of ``n_objects`` (inclusive range) objects of ``objects`` (default: ``object_set()``) placed on the
    unnamed stage's table as the scene generator places them (``muble.stage.layout.TableLayout``); the hidden
    physical properties from ``properties_rng`` (none without it). An object that finds no room is drawn again;
    after ``REDRAWS`` in a row the scene starts over, and after ``RESTARTS`` such starts it is a ``ConfigError``."""
    objects = objects if objects is not None else object_set()
    for _ in range(RESTARTS):
        placed = _placed_objects(rng, n_objects, objects)
        if placed is not None:
            break
    else:
        raise ConfigError(f"synthetic scene {index}: {n_objects[0]} to {n_objects[1]} objects of the object set did "
                          f"not fit on the table in {RESTARTS} layouts; ask for fewer objects")
    specs, models, scene_objects = placed
    if properties_rng is not None:
        # As the scene generator draws them: property by property, each for the objects in scene order that the
        # object set says carry it (ObjectSet.physical_properties).
        for name in physical_properties.PROPERTIES:
            key = physical_properties.SCENE_KEYS[name]
            for o, spec, model in zip(scene_objects, specs, models):
                if physical_properties.carried(name, objects, spec, model):
                    o.extra[key] = physical_properties.sampled(name, properties_rng, model, o.weight_gt)
    return SceneGraph(objects=scene_objects, split="synthetic", image_index=index,
                      image_filename=f"SHOP_VRB2_synthetic_{index:06d}.png")


def keyed_scene(seed: int, key: tuple[int, ...], index: int, n_objects: tuple[int, int] = (3, 6),
                properties: bool = True, objects: ObjectSet | None = None) -> SceneGraph:
    """``sample_scene`` from the synthetic streams of ``seed`` and ``key`` (the caller's numbers for the scene,
    e.g. its index), named ``index``; ``properties``: with the hidden physical properties."""
    return sample_scene(streams.stream(SCENE_STREAM, seed, *key), index, n_objects,
                        properties_rng=streams.stream(PROPERTIES_STREAM, seed, *key) if properties else None,
                        objects=objects)


def sample_scenes(seed: int, count: int, properties: bool = False,
                  objects: ObjectSet | None = None) -> list[SceneGraph]:
    """``count`` scenes, scene ``i`` deterministic from ``(seed, i)``; ``properties``: with the hidden physical
    properties (from a stream of their own, so the scenes are otherwise the same)."""
    return [keyed_scene(seed, (i,), i, properties=properties, objects=objects) for i in range(count)]

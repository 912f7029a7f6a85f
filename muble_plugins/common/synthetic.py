"""Symbolic SHOP-VRB2 scenes sampled from the attribute vocabulary, for generator statistics and tests.

No physics: objects get attributes, flags, a ground-truth weight and stiffness, a bounding box and a spot on the
table, which is all instruction generation and symbolic planning read; with ``properties_rng`` also the hidden
physical properties (``muble.core.physical_properties``) the SHOP-VRB2 object set gives its objects: friction and
a centre of mass to the pickupable ones, loose contents (or none) to the closed pickupable ones. The spots come from the scene generator's
layout sampler (``muble.stage.layout``) on the stage's reach area, with the bounding boxes' outlines for the
objects' footprints.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from muble.core import physical_properties, streams

from muble import SceneGraph, SceneObject
from muble.stage.layout import BoxShape, TableLayout
from muble.stage.table import STAGES, UNNAMED_STAGE

from muble_plugins.common.materials import STIFFNESS_RANGE

COLOURS = ("brown", "white", "gray", "blue", "purple", "green", "yellow", "cyan", "red", "black")
# category: shapes, materials, sizes, (stackable, stack_base, pickupable), weight range g, extents m (x, y, z)
CATEGORIES: dict[str, tuple] = {
    "plate": (("flat",), ("ceramic", "plastic"), ("small", "medium-sized"), (False, True, False),
              (180, 290), (0.16, 0.16, 0.012)),
    "bowl": (("hemisphere",), ("ceramic", "plastic", "glass"), ("small", "medium-sized"), (True, True, True),
             (120, 215), (0.12, 0.12, 0.05)),
    "glass": (("cylindrical", "cuboid"), ("glass", "plastic"), ("medium-sized",), (True, False, True),
              (50, 95), (0.07, 0.07, 0.10)),
    "baking tray": (("flat",), ("metal", "rubber"), ("medium-sized", "large"), (False, True, False),
                    (220, 370), (0.24, 0.16, 0.03)),
    "soda can": (("cylindrical",), ("metal",), ("medium-sized",), (True, False, True),
                 (110, 130), (0.066, 0.066, 0.12)),
    "food box": (("cylindrical", "cuboid"), ("plastic",), ("small", "medium-sized"), (False, True, False),
                 (150, 215), (0.10, 0.10, 0.10)),
    "mug": (("cylindrical",), ("ceramic",), ("small", "medium-sized"), (True, False, True),
            (55, 115), (0.10, 0.08, 0.09)),
    "chopping board": (("cuboid", "irregularly shaped"), ("plastic", "rubber", "wooden"), ("large",),
                       (False, True, False), (360, 500), (0.24, 0.15, 0.02)),
    "thermos": (("cylindrical",), ("metal",), ("medium-sized",), (False, False, True),
                (235, 255), (0.08, 0.08, 0.25)),
    "wine glass": (("irregularly shaped",), ("glass", "plastic"), ("medium-sized",), (False, False, True),
                   (95, 115), (0.08, 0.08, 0.18)),
}


CLOSED = ("soda can", "thermos", "food box")  # closed containers, which can hold loose contents

# A synthetic scene's streams (muble.core.streams), each keyed by the caller's seed and scene key: the stiffnesses
# and the hidden properties apart from the rest, so that drawing them changes nothing else a scene holds.
SCENE_STREAM = streams.declare("synthetic.scene", "a synthetic symbolic scene's object count, categories, "
                               "attribute words, placements and weights (muble_plugins.common.synthetic; the "
                               "caller's scene key)")
STIFFNESS_STREAM = streams.declare("synthetic.stiffness", "a synthetic scene's stiffnesses (the caller's scene key)")
PROPERTIES_STREAM = streams.declare("synthetic.properties", "a synthetic scene's hidden physical properties (the "
                                    "caller's scene key)")
PLACE_TRIES = 20  # poses tried per object before another category is drawn in its stead


def _pick(rng: np.random.Generator, items: tuple) -> str:
    return items[int(rng.integers(len(items)))]


def sample_scene(rng: np.random.Generator, index: int = 0, n_objects: tuple[int, int] = (3, 6),
                 stiffness_rng: np.random.Generator | None = None,
                 properties_rng: np.random.Generator | None = None) -> SceneGraph:
    """A scene of ``n_objects`` (inclusive range) objects placed on the unnamed stage's table as the scene generator
    places them (``muble.stage.layout.TableLayout``); stiffnesses come from ``stiffness_rng`` (none without it),
    the hidden physical properties from ``properties_rng`` (none without it)."""
    n = int(rng.integers(n_objects[0], n_objects[1] + 1))
    names = list(CATEGORIES)
    objects: list[SceneObject] = []
    layout = TableLayout.on_stage(STAGES[UNNAMED_STAGE])
    while len(objects) < n:
        name = names[int(rng.integers(len(names)))]
        shapes, materials, sizes, flags, (w0, w1), ext = CATEGORIES[name]
        material = _pick(rng, materials)
        scale = {"small": 0.8, "medium-sized": 1.0, "large": 1.1}[size := _pick(rng, sizes)]
        ex, ey, ez = (e * scale for e in ext)
        placement = layout.try_place(BoxShape(ex, ey), rng, PLACE_TRIES)
        if placement is None:
            continue  # no room for this one: sample another category
        objects.append(SceneObject(
            id=len(objects), model=name.replace(" ", "_") + "1", name=name, shape=_pick(rng, shapes), size=size,
            material=material, colour="transparent" if material == "glass" else _pick(rng, COLOURS),
            position=placement.position, orientation=placement.quat,
            weight_gt=round(float(rng.uniform(w0, w1)), 1), stackable=flags[0], stack_base=flags[1],
            pickupable=flags[2], rotation=math.degrees(placement.yaw), bbox={"x": ex, "y": ey, "z": ez},
        ))
    if stiffness_rng is not None:
        # The SHOP-VRB2 object set's ground-truth stiffness ranges (N/m) by material, drawn log-uniformly from a
        # stream of their own, so that they change nothing else a seed gives.
        for o in objects:
            low, high = STIFFNESS_RANGE[o.material]
            o.stiffness = round(float(np.exp(stiffness_rng.uniform(np.log(low), np.log(high)))), 1)
    if properties_rng is not None:
        for o in objects:
            if not o.pickupable:
                continue
            model = SimpleNamespace(extents=(o.bbox["x"], o.bbox["y"], o.bbox["z"]), closed=o.name in CLOSED)
            carried = ("friction", "com_offset") + (("contents",) if model.closed else ())
            for name in carried:
                o.extra[physical_properties.SCENE_KEYS[name]] = physical_properties.sampled(
                    name, properties_rng, model, o.weight_gt)
    return SceneGraph(objects=objects, split="synthetic", image_index=index,
                      image_filename=f"SHOP_VRB2_synthetic_{index:06d}.png")


def keyed_scene(seed: int, key: tuple[int, ...], index: int, n_objects: tuple[int, int] = (3, 6),
                properties: bool = True) -> SceneGraph:
    """``sample_scene`` from the synthetic streams of ``seed`` and ``key`` (the caller's numbers for the scene,
    e.g. its index), named ``index``; ``properties``: with the hidden physical properties."""
    return sample_scene(streams.stream(SCENE_STREAM, seed, *key), index, n_objects,
                        stiffness_rng=streams.stream(STIFFNESS_STREAM, seed, *key),
                        properties_rng=streams.stream(PROPERTIES_STREAM, seed, *key) if properties else None)


def sample_scenes(seed: int, count: int, properties: bool = False) -> list[SceneGraph]:
    """``count`` scenes, scene ``i`` deterministic from ``(seed, i)``; ``properties``: with the hidden physical
    properties (from a stream of their own, so the scenes are otherwise the same)."""
    return [keyed_scene(seed, (i,), i, properties=properties) for i in range(count)]

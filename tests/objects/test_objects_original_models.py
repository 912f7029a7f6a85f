"""The original release's models rebuilt from their measurements: size, handle, rest, masks, and no change to
this catalogue's own models."""
from __future__ import annotations

import dataclasses
import math
import statistics

import numpy as np
import pytest

from muble.io.scene_io import load_scenes
from muble_plugins.objects.original import ORIGINAL_MODELS, ORIGINAL_MODEL_PARAM, original_fit
from muble_plugins.objects.original_models import ORIGINAL_GEOMETRY
from muble_plugins.objects.shopvrb2 import CATALOGUE
from tests.support.object_checks import drop

from tests.objects.test_objects_original import original_object, spec

# Bounding boxes (x, y, z in m) the original release records for its objects (its demo scene files,
# demo/demo_input/scenes): independent of the measurements the models here are built from.
RECORDED_BBOX = {
    ("plate2", 0.6): (0.1579, 0.1579, 0.0102), ("bowl2", 0.45): (0.0737, 0.0737, 0.0405),
    ("glass5", 0.6): (0.066, 0.066, 0.0538), ("baking_tray1", 0.6): (0.21, 0.1409, 0.0112),
    ("soda_can", 0.6): (0.0476, 0.0475, 0.0828), ("food_box2", 0.6): (0.1032, 0.1043, 0.063),
    ("mug1", 0.45): (0.0598, 0.0423, 0.0524), ("mug1", 0.6): (0.0798, 0.0564, 0.0698),
    ("glass1", 0.6): (0.0544, 0.0544, 0.09), ("mug2", 0.6): (0.0812, 0.0564, 0.072),
    ("chopping_board2", 0.6): (0.18, 0.1252, 0.0062), ("bowl1", 0.6): (0.0963, 0.0963, 0.0536),
    ("glass4", 0.6): (0.0499, 0.0499, 0.0547), ("bowl3", 0.6): (0.1025, 0.1032, 0.054),
    ("thermos1", 0.6): (0.0441, 0.0439, 0.147), ("glass3", 0.6): (0.0387, 0.0387, 0.0696),
    ("wine_glass1", 0.6): (0.0399, 0.0399, 0.1125), ("baking_tray2", 0.45): (0.135, 0.0969, 0.0081),
    ("mug3", 0.6): (0.0884, 0.0636, 0.072), ("wine_glass2", 0.6): (0.0285, 0.0285, 0.1287),
    ("chopping_board3", 0.6): (0.2527, 0.1061, 0.0075),
}
FOOTPRINT_TOLERANCE = 0.04  # relative: the recorded bbox is of the original's Blender model
HEIGHT_TOLERANCE = 0.05  # relative: wine_glass1 floats 3 mm above the table in the original, stands on it here
# Mask IoU floors on the original's demo scenes (masks recorded in its scene file), MuJoCo renderer.
MASK_IOU_FLOOR = 0.85
MASK_IOU_MEDIAN_FLOOR = 0.9


def test_every_original_model_has_its_measured_geometry():
    assert {m for models in ORIGINAL_MODELS.values() for m in models} == set(ORIGINAL_GEOMETRY)


def original_of(model: str, **fields):
    """An object of the original's files naming ``model``, with the shape word of this catalogue's model."""
    category = next(c for c, models in ORIGINAL_MODELS.items() if model in models)
    shape = (CATALOGUE[category].model(model) or next(iter(CATALOGUE[category].variants.values())))[0]
    return original_object(name=category, model=model, shape=shape, material="plastic", **fields)


@pytest.mark.parametrize("model,scale_factor", sorted(RECORDED_BBOX))
def test_original_objects_have_the_size_the_original_records(shopvrb2, model, scale_factor):
    built = spec(shopvrb2, original_of(model, scale_factor=scale_factor,
                                       size="small" if scale_factor < 0.6 else "medium-sized"))
    assert original_fit(built) == (model, scale_factor)
    extents = shopvrb2.build(built).extents
    x, y, z = RECORDED_BBOX[(model, scale_factor)]
    assert extents[0] == pytest.approx(x, rel=FOOTPRINT_TOLERANCE)
    assert extents[1] == pytest.approx(y, rel=FOOTPRINT_TOLERANCE)
    assert extents[2] == pytest.approx(z, rel=HEIGHT_TOLERANCE)


def test_an_original_mug_has_its_handle_where_the_original_has_it(shopvrb2):
    # The original mug1 (import scale 1): body 94 mm across, its axis 15.6 mm along +x from the model's origin,
    # the handle towards -x reaching 86 mm from the axis (70.4 mm from the origin), from 26 to 95 mm up.
    s = 0.6
    model = shopvrb2.build(spec(shopvrb2, original_object(scale_factor=s)))
    v = model.visual.vertices
    assert v[:, 0].min() == pytest.approx(-0.0704 * s, abs=0.0015)
    assert v[:, 0].max() == pytest.approx((0.0156 + 0.047) * s, abs=0.0015)
    handle = v[v[:, 0] < (0.0156 - 0.047) * s - 0.002]
    assert handle[:, 2].min() == pytest.approx(0.026 * s, abs=0.004)
    assert handle[:, 2].max() == pytest.approx(0.095 * s, abs=0.004)
    # Grasp frames of the handle are on it (towards -x), and collision parts cover it as the visual mesh does.
    assert min(f.position[0] for f in model.grasp_frames) < (0.0156 - 0.047) * s
    collision_x = min(p.vertices[:, 0].min() for p in model.collision_parts)
    assert collision_x == pytest.approx(v[:, 0].min(), abs=0.001)


@pytest.mark.parametrize("model", ["mug1", "bowl2", "bowl3", "glass5", "wine_glass1", "food_box2"])
def test_original_objects_rest_upright(shopvrb2, model):
    built = shopvrb2.build(spec(shopvrb2, original_of(model, weight_gt=120.0)))
    report = drop(built, height=0.03, seconds=2.0)
    assert report.penetration <= 0.002 and report.speed[0] < 0.001 and report.tilt_deg[0] < 2.0


def test_this_catalogues_objects_are_built_as_before(shopvrb2):
    # An object of this project's files (scale factor 0.85 or more) gets the catalogue's own model.
    obj = original_object(scale_factor=1.0)
    built = spec(shopvrb2, obj)
    assert ORIGINAL_MODEL_PARAM not in built.params
    direct = dataclasses.replace(built, params={})
    assert np.array_equal(shopvrb2.build(built).visual.vertices, shopvrb2.build(direct).visual.vertices)
    assert shopvrb2.build(built).visual.vertices[:, 0].max() > 0.04  # handle towards +x, as this catalogue has it


@pytest.mark.gl
def test_masks_match_the_originals_demo_scenes(shopvrb2, reference_dir):
    from muble.generation.ground_truth import decode_mask
    from muble.plugins.registry import get_registry
    from muble.sim.build import env_from_object_set
    from tests.support.image_likeness import mask_iou

    _, scenes = load_scenes(reference_dir / "NS_AP_demo_scenes.json")
    ious = {}
    for scene in scenes:
        env = env_from_object_set(scene, "shopvrb2")
        renderer = get_registry().create("renderer", "mujoco", {"width": 848, "height": 480, "segmentation": True})
        try:
            env.reset()
            renderer.setup(scene, env.model)
            frame = renderer.render(env.data, "front")
            for obj in scene.objects:
                mask = decode_mask(obj.mask)
                assert mask.shape == frame.segmentation.shape
                ious[(scene.image_index, obj.id, obj.model)] = mask_iou(frame.segmentation == obj.id, mask)
        finally:
            renderer.close()
            env.close()
    worst = min(ious, key=ious.get)
    assert ious[worst] >= MASK_IOU_FLOOR, f"{worst}: IoU {ious[worst]:.3f}"
    assert statistics.median(ious.values()) >= MASK_IOU_MEDIAN_FLOOR
    assert not math.isnan(sum(ious.values()))


def test_original_objects_take_the_originals_paint_colours(shopvrb2):
    """The original's generator painted with its own palette (green 29, 105, 20 of 255); this project's objects keep
    the catalogue's colours, and colours the palette does not hold (white) keep theirs too."""
    from muble_plugins.objects.catalogue import COLOUR_RGBA

    green = shopvrb2.build(spec(shopvrb2, original_of("mug1", colour="green", scale_factor=0.6)))
    assert green.rgba == pytest.approx((29 / 255, 105 / 255, 20 / 255, 1.0))
    ours = shopvrb2.build(spec(shopvrb2, original_of("mug1", colour="green", scale_factor=1.0)))
    assert ours.rgba == pytest.approx(COLOUR_RGBA["green"])
    white = shopvrb2.build(spec(shopvrb2, original_of("bowl1", colour="white", scale_factor=0.6)))
    assert white.rgba == pytest.approx(COLOUR_RGBA["white"])

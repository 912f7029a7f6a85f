"""Scene objects of the original SHOP-VRB2 files: model names, scale factors, shape words, material defaults."""
from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pytest

from muble.core.errors import SceneValidationError
from muble.core.scene import SceneGraph, SceneObject
from muble.io.scene_io import load_scenes
from muble.sim.build import object_models
from muble_plugins.objects.catalogue import FRICTION, default_stiffness
from muble_plugins.objects.original import ORIGINAL_MODELS
from muble_plugins.objects.shopvrb2 import CATALOGUE
from muble_plugins.objects.testing import spec_of
from tests.support.object_checks import drop


def original_object(obj_id=0, **fields) -> SceneObject:
    """An object as the original release writes it: no stiffness, its import scale, a light weight."""
    values = dict(model="mug1", name="mug", shape="cylindrical", size="medium-sized", material="ceramic",
                  colour="red", position=np.array([0.5, 0.0, 0.0]), orientation=np.array([1.0, 0, 0, 0]),
                  weight_gt=85.0, stackable=True, stack_base=False, pickupable=True, scale_factor=0.6)
    values.update(fields)
    return SceneObject(id=obj_id, **values)


def spec(shopvrb2, obj):
    return shopvrb2.spec_from_scene_object(obj if obj.stiffness else dataclasses.replace(obj, stiffness=1e4))


def test_every_original_model_has_a_model_here(shopvrb2):
    for category, models in ORIGINAL_MODELS.items():
        for model in models:
            shape = (CATALOGUE[category].model(model) or next(iter(CATALOGUE[category].variants.values())))[0]
            obj = original_object(name=category, model=model, shape=shape, material="plastic")
            built = shopvrb2.spec_from_scene_object(dataclasses.replace(obj, stiffness=1e4))
            assert CATALOGUE[category].model(built.model) is not None


def test_original_scale_factors_are_converted(shopvrb2):
    assert spec(shopvrb2, original_object(size="small", scale_factor=0.45)).scale == pytest.approx(0.85)
    assert spec(shopvrb2, original_object(scale_factor=0.6)).scale == pytest.approx(1.0)
    assert spec(shopvrb2, original_object(size="medium-sized", scale_factor=0.45)).scale == pytest.approx(0.75)
    # This project's own scale factors are the multiple of the medium size, as before.
    assert spec(shopvrb2, original_object(size="large", scale_factor=1.15)).scale == pytest.approx(1.15)


def test_a_model_the_original_lacks_is_fitted_to_its_recorded_footprint(shopvrb2):
    # The original's own models are built with their measured shape (test_objects_original_models); any other
    # model at an original scale factor is this catalogue's, fitted to the recorded bbox.
    can = dict(name="soda can", model="soda_can2", material="metal", colour="gray")
    full = spec(shopvrb2, original_object(**can))
    small = spec(shopvrb2, original_object(**can, bbox={"x": 0.05, "y": 0.05, "z": 0.12}))
    extent = max(shopvrb2.build(small).extents[:2])
    assert small.scale < full.scale and extent == pytest.approx(0.05, rel=0.05)
    assert not small.params
    tiny = spec(shopvrb2, original_object(**can, bbox={"x": 0.01, "y": 0.01, "z": 0.07}))
    assert tiny.scale == pytest.approx(0.5)


def test_shape_words_pick_the_model_with_that_shape(shopvrb2):
    box = original_object(name="food box", model="food_box2", shape="cylindrical", material="plastic",
                          stackable=False, stack_base=True, pickupable=False)
    assert spec(shopvrb2, box).model == "food_box1"
    board = original_object(name="chopping board", model="chopping_board3", shape="irregularly shaped",
                            material="wooden", size="large")
    assert CATALOGUE["chopping board"].model(spec(shopvrb2, board).model)[0] == "irregularly shaped"
    assert spec(shopvrb2, original_object(name="glass", model="glass5", shape="cuboid")).model == "glass5"


def test_missing_stiffness_and_friction_come_from_the_material(shopvrb2, caplog, monkeypatch):
    import muble.sim.build

    monkeypatch.setattr(muble.sim.build, "_defaults_logged", set())  # logged once per process: earlier tests may have
    scene = SceneGraph(objects=[original_object(0, material="metal", colour="gray"),
                                original_object(1, material="plastic", position=np.array([0.5, 0.2, 0.0]))])
    with caplog.at_level(logging.WARNING):
        models = object_models(scene, shopvrb2, "shopvrb2")
    assert models[1].stiffness == pytest.approx(default_stiffness("plastic"))
    assert models[0].friction == FRICTION["metal"] and models[1].friction == FRICTION["plastic"]
    assert "default for plastic" in caplog.text


@pytest.mark.parametrize("change,field,says", [
    ({"model": "mug9"}, "file", "unknown 'mug' model 'mug9'"),
    ({"name": "teapot"}, "name", "unknown category 'teapot'"),
    ({"shape": "cuboid"}, "shape", "unknown shape 'cuboid' of a mug"),
    ({"material": "paper"}, "material", "unknown material 'paper'"),
    ({"colour": "mauve"}, "colour", "unknown colour 'mauve'"),
    ({"size": "huge"}, "size", "unknown size 'huge'"),
])
def test_unmappable_objects_name_object_and_field(shopvrb2, change, field, says):
    obj = original_object(3, stiffness=1e4, **change)
    with pytest.raises(SceneValidationError) as err:
        shopvrb2.spec_from_scene_object(obj)
    assert err.value.obj == 3 and err.value.field == field and says in str(err.value)


@pytest.mark.parametrize("category,model", [("glass", "glass4"), ("glass", "glass5"),
                                            ("wine glass", "wine_glass3")])
@pytest.mark.parametrize("size", ["small", "medium-sized"])
def test_added_original_models_rest_upright(shopvrb2, category, model, size):
    report = drop(shopvrb2.build(spec_of(shopvrb2, category, model, size)), height=0.05, seconds=2.0)
    assert report.penetration <= 0.002 and report.speed[0] < 0.001 and report.tilt_deg[0] < 2.0


def test_added_models_are_never_sampled(shopvrb2):
    rng = np.random.default_rng(0)
    sampled = {shopvrb2.sample(rng, c).model for c in ("glass", "wine glass") for _ in range(200)}
    assert not sampled & {"glass4", "glass5", "wine_glass3"}


def test_every_demo_scene_builds(shopvrb2, reference_dir):
    _, scenes = load_scenes(reference_dir / "NS_AP_demo_scenes.json")
    for scene in scenes:
        models = object_models(scene, shopvrb2, "shopvrb2")
        assert len(models) == len(scene.objects)
        assert all(m.mass * 1000 == pytest.approx(o.weight_gt) for o, m in zip(scene.objects, models.values()))

"""Held-out conditions for generalisation splits: model and finish filters, inner/outer property ranges, camera
and lamp jitter. Each is an addition: at its default every sample and every scene is what it was without it."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from muble import ConfigError, get_registry
from muble.generation import SceneGenerator, checks, ground_truth
from muble.generation.contact_sheet import models_from_scene, placements_from_scene
from muble.generation.ground_truth import decode_mask
from muble.generation.staging import LAMPS
from muble.io.scene_io import scene_to_dict
from muble.stage.camera import CameraParams, matrix_to_euler_xyz
from muble_plugins.common.materials import STIFFNESS_RANGE
from muble_plugins.objects.catalogue import FRICTION, SIZE_SCALES, CatalogueObjectSet
from muble_plugins.objects.heldout import finish_name
from muble_plugins.objects.shopvrb2 import CATALOGUE, ShopVrb2Objects
from muble_plugins.objects.ycb import YcbObjects
from tests.generation.builtin import BUILTIN

SAMPLES = 500


def _specs(objects: CatalogueObjectSet, seed: int = 2024, n: int = SAMPLES) -> list:
    rng = np.random.default_rng(seed)
    return [objects.sample(rng) for _ in range(n)]


def _bytes(specs: list) -> bytes:
    return json.dumps([dataclasses.asdict(s) for s in specs], sort_keys=True).encode()


def _finish(spec):
    return next(f for f in CATALOGUE[spec.category].finishes if f.material == spec.material)


def _reference_sample(objects: CatalogueObjectSet, rng: np.random.Generator):
    """The catalogue's draws as they were before the held-out options existed: category, model, finish, colour,
    size, one uniform weight, one log-uniform stiffness, in that order, from the full catalogue tables."""
    names = list(objects.catalogue)
    name = names[int(rng.integers(len(names)))]
    cat = objects.catalogue[name]
    model = list(cat.variants)[int(rng.integers(len(cat.variants)))]
    finish = cat.finishes[int(rng.integers(len(cat.finishes)))]
    colour = finish.colours[int(rng.integers(len(finish.colours)))]
    size = cat.sizes[int(rng.integers(len(cat.sizes)))]
    scale = SIZE_SCALES[size]
    weight = float(rng.uniform(*finish.weight_g)) * scale**cat.mass_exponent
    k_low, k_high = STIFFNESS_RANGE[finish.material]
    stiffness = float(math.exp(rng.uniform(math.log(k_low), math.log(k_high))))
    return (name, model, colour, finish.material, size, scale, round(weight, 1), round(stiffness, 1),
            FRICTION[finish.material])


# --- the stream at default options --------------------------------------------------------------------------

@pytest.mark.parametrize("cls", [ShopVrb2Objects, YcbObjects])
def test_default_options_draw_exactly_the_stream_of_before(cls):
    plain = _specs(cls(cache_dir=None))
    explicit = _specs(cls(cache_dir=None, exclude_models=[], only_models=[], exclude_finishes=[], only_finishes=[],
                          property_range="all", inner_fraction=0.6))
    # Listing every model and finish filters nothing, so it draws the same indices into the same tables.
    every_model = [m for c in cls.catalogue.values() for m in c.variants]
    every_finish = [finish_name(col, f.material) for c in cls.catalogue.values() for f in c.finishes
                    for col in f.colours]
    listed = _specs(cls(cache_dir=None, only_models=every_model, only_finishes=every_finish))
    assert _bytes(plain) == _bytes(explicit) == _bytes(listed)
    rng = np.random.default_rng(2024)
    reference = [_reference_sample(cls(cache_dir=None), rng) for _ in range(SAMPLES)]
    assert [(s.category, s.model, s.colour, s.material, s.size, s.scale, s.weight_g, s.stiffness, s.friction)
            for s in plain] == reference


# --- models -------------------------------------------------------------------------------------------------

def test_excluded_models_are_never_sampled():
    excluded = ["mug1", "mug2", "bowl3", "wine_glass1"]
    objects = ShopVrb2Objects(cache_dir=None, exclude_models=excluded)
    specs = _specs(objects)
    assert not {s.model for s in specs} & set(excluded)
    assert {"mug3", "bowl1", "bowl2", "wine_glass2"} <= {s.model for s in specs}
    assert objects.models("mug") == ["mug3"] and objects.categories() == ShopVrb2Objects(cache_dir=None).categories()


def test_only_models_restrict_models_and_categories():
    only = ["mug1", "bowl2", "plate1"]
    objects = ShopVrb2Objects(cache_dir=None, only_models=only)
    assert objects.categories() == ["bowl", "mug", "plate"]
    specs = _specs(objects)
    assert {s.model for s in specs} == set(only)


def test_a_category_whose_models_are_all_excluded_is_not_sampled():
    objects = ShopVrb2Objects(cache_dir=None, exclude_models=["soda_can", "soda_can2"])
    assert "soda can" not in objects.categories()
    assert "soda can" not in {s.category for s in _specs(objects)}
    with pytest.raises(ConfigError, match="soda can"):
        objects.sample(np.random.default_rng(0), "soda can")
    with pytest.raises(ConfigError, match="none of the categories"):
        ShopVrb2Objects(cache_dir=None, categories=["soda can"], exclude_models=["soda_can", "soda_can2"])


def test_an_unknown_model_or_finish_names_the_valid_ones():
    with pytest.raises(ConfigError) as err:
        ShopVrb2Objects(cache_dir=None, exclude_models=["mug9"])
    message = str(err.value)
    assert "mug9" in message and all(m in message for m in ("mug1", "bowl3", "wine_glass2", "soda_can2"))
    assert "glass4" not in message  # imported models are never sampled, so they are no choice here
    with pytest.raises(ConfigError, match="transparent glass"):
        ShopVrb2Objects(cache_dir=None, only_finishes=["red glass"])
    with pytest.raises(ConfigError, match="003_cracker_box"):
        YcbObjects(cache_dir=None, only_models=["mug1"])
    # Through the registry, as a Hydra override reaches it.
    with pytest.raises(ConfigError, match="valid shopvrb2 model names"):
        get_registry().create("object_set", "shopvrb2", {"cache_dir": None, "only_models": ["cup"]})
    with pytest.raises(ConfigError, match="inner, outer"):
        get_registry().create("object_set", "shopvrb2", {"cache_dir": None, "property_range": "middle"})
    with pytest.raises(ConfigError, match="inner_fraction"):
        get_registry().create("object_set", "shopvrb2", {"cache_dir": None, "inner_fraction": 1.0})


# --- finishes -----------------------------------------------------------------------------------------------

def test_excluded_finishes_are_never_sampled():
    excluded = ["red plastic", "transparent glass", "white ceramic"]
    specs = _specs(ShopVrb2Objects(cache_dir=None, exclude_finishes=excluded))
    drawn = {finish_name(s.colour, s.material) for s in specs}
    assert not drawn & set(excluded)
    assert {"blue plastic", "black ceramic", "red metal"} <= drawn
    # Glass objects stay, in their plastic finishes: only the (colour, material) pairs named are gone.
    assert "glass" in {s.category for s in specs}


def test_only_finishes_restrict_finishes_and_categories():
    only = ["red plastic", "white ceramic"]
    objects = ShopVrb2Objects(cache_dir=None, only_finishes=only)
    specs = _specs(objects)
    assert {finish_name(s.colour, s.material) for s in specs} == set(only)
    # Soda cans are metal only, chopping boards come in white plastic but not red: both categories drop out.
    assert "soda can" not in objects.categories() and "chopping board" in objects.categories()


# --- property ranges ----------------------------------------------------------------------------------------

def test_inner_and_outer_properties_lie_in_their_parts_and_never_overlap():
    fraction = 0.6
    parts = {part: _specs(ShopVrb2Objects(cache_dir=None, property_range=part, inner_fraction=fraction), seed=9)
             for part in ("inner", "outer")}
    seen: dict[str, dict[tuple, list[float]]] = {"inner": {}, "outer": {}}
    tails = {"lower": 0, "upper": 0}
    for part, specs in parts.items():
        for s in specs:
            low, high = _finish(s).weight_g
            factor = s.scale ** CATALOGUE[s.category].mass_exponent
            tail = (high - low) * (1 - fraction) / 2
            weight = s.weight_g / factor  # back to the medium-size range the finish gives
            slack = 0.05 / factor + 1e-9  # the file keeps 0.1 g
            assert low - slack <= weight <= high + slack
            k_low, k_high = (math.log(k) for k in STIFFNESS_RANGE[s.material])
            k_tail = (k_high - k_low) * (1 - fraction) / 2
            k = math.log(s.stiffness)
            k_slack = 0.05 / s.stiffness + 1e-12
            if part == "inner":
                assert low + tail - slack <= weight <= high - tail + slack
                assert k_low + k_tail - k_slack <= k <= k_high - k_tail + k_slack
            elif high > low:
                assert weight <= low + tail + slack or weight >= high - tail - slack
                assert k <= k_low + k_tail + k_slack or k >= k_high - k_tail - k_slack
                tails["lower" if weight < (low + high) / 2 else "upper"] += 1
            seen[part].setdefault((s.category, s.material, s.size), []).append(s.weight_g)
    # The two tails are drawn about equally often.
    assert min(tails.values()) > 0.4 * sum(tails.values())
    # Per kind and size of object, no outer weight lies within the span the inner ones covered.
    for key, inner in seen["inner"].items():
        for w in seen["outer"].get(key, []):
            assert not min(inner) < w < max(inner), (key, w)


def test_property_ranges_keep_the_filters_and_the_other_draws():
    """The part of a range changes only the weight and stiffness drawn: same categories, models, finishes."""
    a = _specs(ShopVrb2Objects(cache_dir=None))
    b = _specs(ShopVrb2Objects(cache_dir=None, property_range="inner"))
    assert [(s.category, s.model, s.colour, s.size) for s in a] == [(s.category, s.model, s.colour, s.size)
                                                                    for s in b]


# --- camera and lamp jitter ---------------------------------------------------------------------------------

FAST = {**BUILTIN, "stability": False, "reach_check": False}
JITTER = {"camera_jitter_m": 0.02, "camera_jitter_deg": 1.5, "lamp_jitter": 0.3}



def test_staging_is_default_without_jitter_and_within_bounds_with_it(object_set):
    plain = SceneGenerator(FAST, seed=5, object_set=object_set)
    jittered = SceneGenerator({**FAST, **JITTER}, seed=5, object_set=object_set)
    cameras_only = SceneGenerator({**FAST, "camera_jitter_m": 0.02, "camera_jitter_deg": 1.5}, seed=5,
                                  object_set=object_set)
    lamps_only = SceneGenerator({**FAST, "lamp_jitter": 0.3}, seed=5, object_set=object_set)
    cfg = plain.config
    for index in range(20):
        default = plain.staging(index)
        assert default.camera is plain.camera and default.lamps == LAMPS and default.lamp_energy is None
        staged = jittered.staging(index)
        offset = staged.camera.position - np.asarray(cfg.camera_position)
        assert np.all(np.abs(offset) <= 0.02) and np.any(offset != 0)
        turn = matrix_to_euler_xyz(staged.camera.rotation) - np.asarray(cfg.camera_rotation)
        assert np.all(np.abs(turn) <= 1.5 + 1e-9)
        assert staged.directions == ground_truth.directions(staged.camera)
        for name, position in LAMPS.items():
            assert np.all(np.abs(np.subtract(staged.lamps[name], position)) <= 0.3)
            assert 0.7 <= staged.lamp_energy[name] <= 1.3
        # Each jitter has its own stream: one does not move the other.
        assert np.array_equal(cameras_only.staging(index).camera.position, staged.camera.position)
        assert cameras_only.staging(index).lamps == LAMPS
        assert lamps_only.staging(index).camera is lamps_only.camera
        assert lamps_only.staging(index).lamps == staged.lamps
    assert jittered.staging(3).camera.position.tolist() != jittered.staging(4).camera.position.tolist()
    assert jittered.staging(3).camera.position.tolist() == jittered.staging(3).camera.position.tolist()
    with pytest.raises(ConfigError, match="lamp_jitter"):
        SceneGenerator({**FAST, "lamp_jitter": -0.1}, seed=5, object_set=object_set)
    for g in (plain, jittered, cameras_only, lamps_only):
        g.close()


@pytest.mark.gl
def test_jitter_moves_camera_and_lamps_and_leaves_the_objects(object_set):
    plain = SceneGenerator(FAST, seed=5, object_set=object_set)
    zeros = SceneGenerator({**FAST, "camera_jitter_m": 0.0, "camera_jitter_deg": 0.0, "lamp_jitter": 0.0}, seed=5,
                           object_set=object_set)
    jittered = SceneGenerator({**FAST, **JITTER}, seed=5, object_set=object_set)
    fresh = get_registry().create("renderer", "mujoco", {"width": 848, "height": 480, "rgb": False,
                                                         "depth": False, "segmentation": True})
    try:
        for index in (0, 1):
            a = scene_to_dict(plain.generate(index))
            assert json.dumps(scene_to_dict(zeros.generate(index))) == json.dumps(a)
            scene = jittered.generate(index)
            b = scene_to_dict(scene)
            assert "lamp_energy" not in a and a["lamp_params"] == LAMPS
            keep = ("3d_coords", "orientation", "rotation", "file", "name", "colour", "material", "size",
                    "weight_gt", "stiffness")
            assert [{k: o[k] for k in keep} for o in a["objects"]] == [{k: o[k] for k in keep} for o in b["objects"]]
            assert b["camera_params"]["position"] != a["camera_params"]["position"]
            assert set(b["lamp_energy"]) == set(LAMPS) and b["lamp_params"] != a["lamp_params"]
            # Pixel coordinates, directions and masks are those of the file's own camera.
            camera = CameraParams.from_scene_params(b["camera_params"])
            for o in b["objects"]:  # the file's Euler angles round-trip to the last bit or two
                assert o["pixel_coords"] == pytest.approx(ground_truth.pixel_coords(camera, np.asarray(o["3d_coords"])))
            for name, direction in b["directions"].items():
                # The file keeps 9 decimals (ground_truth.FILE_DECIMALS) of the directions and the camera's angles.
                assert direction == pytest.approx(ground_truth.directions(camera)[name], abs=1e-8)
            models, placements = models_from_scene(object_set, scene), placements_from_scene(scene)
            view, data = checks.view_model(models, placements, camera, jittered.config.table_x,
                                           jittered.config.table_y)
            fresh.setup(None, view)
            seen = fresh.render(data, checks.CAMERA_NAME).segmentation
            for obj in scene.objects:
                mask = decode_mask(obj.mask)
                assert (mask & (seen == obj.id)).sum() >= 0.99 * max(mask.sum(), (seen == obj.id).sum())
            # The shared view model is aimed back: the next default scene is drawn by the default camera.
            assert json.dumps(scene_to_dict(plain.generate(index))) == json.dumps(a)
    finally:
        fresh.close()
        for g in (plain, zeros, jittered):
            g.close()


@pytest.mark.gl
def test_six_and_seven_objects_are_placed(object_set):
    gen = SceneGenerator({**FAST, "min_objects": 6, "count_probabilities": [0.5, 0.5]}, seed=5,
                         object_set=object_set)
    try:
        counts = {len(gen.generate(index).objects) for index in range(4)}
        assert counts <= {6, 7}
        assert len(gen.generate(10, objects=7).objects) == 7
    finally:
        gen.close()

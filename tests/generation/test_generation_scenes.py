"""Generated scenes: mesh clearance, visibility, rest, weight gaps, determinism and bounded failure."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from muble import ConfigError
from muble.generation import SceneGenerator
from muble.generation.checks import settle
from muble.generation.ground_truth import decode_mask
from muble.generation.placement import CollisionMesh, min_pairwise_distance
from muble.io.scene_io import scene_from_dict, scene_to_dict, validate_scene
from muble.stage.layout import Placement
from tests.generation.builtin import BUILTIN

pytestmark = pytest.mark.gl



@pytest.fixture(scope="module")
def generator(object_set):
    g = SceneGenerator(BUILTIN, seed=7, object_set=object_set)
    yield g
    g.close()


def _models(object_set, scene):
    from muble.core.objects import ObjectSpec

    models = []
    for o in scene.objects:
        spec = ObjectSpec("shopvrb2", o.name, o.model, o.colour, o.material, o.size, o.shape,
                          o.scale_factor, o.weight_gt, 1000.0)
        models.append(object_set.build(spec))
    return models


def test_scenes_meet_every_acceptance_rule(generator, object_set):
    cfg = generator.config
    for index in range(3):
        scene = generator.generate(index)
        assert 4 <= len(scene.objects) <= 5
        models = _models(object_set, scene)
        placements = [Placement(o.position[0], o.position[1], np.radians(o.rotation)) for o in scene.objects]
        # mesh clearance, recomputed from the file
        assert min_pairwise_distance([CollisionMesh(m) for m in models], placements) >= cfg.margin - 1e-9
        # every object visible on the full-size mask
        for o in scene.objects:
            assert decode_mask(o.mask).sum() >= cfg.min_visible_pixels
        assert decode_mask(scene.table["mask"]).sum() > 10000
        # rest: settle again from the file's poses, with the file's weights
        for m, o in zip(models, scene.objects):
            assert m.mass == pytest.approx(o.weight_gt / 1000)
        moved = settle(models, placements, cfg.table_x, cfg.table_y, generator.timestep, 1.0)
        assert moved.max() <= 0.005
        weights = sorted(o.weight_gt for o in scene.objects)
        assert min(np.diff(weights)) >= cfg.min_weight_gap
        validate_scene(scene)


def test_relationships_follow_the_camera(generator):
    scene = generator.generate(11)
    pos = {o.id: o.position for o in scene.objects}
    for i, right_of_i in enumerate(scene.relationships["right"]):
        for j in right_of_i:
            assert np.dot(pos[j] - pos[i], scene.directions["right"]) > 0
            assert i in scene.relationships["left"][j]
    # the front camera at x = 1.15 looks towards -x: "front" points at it, "right" is nearly +y
    assert scene.directions["front"][0] > 0.99 and scene.directions["right"][1] > 0.99


def test_same_seed_and_index_give_identical_bytes(object_set):
    cfg = {**BUILTIN, "stability": False}
    a = SceneGenerator(cfg, seed=3, object_set=object_set)
    b = SceneGenerator(cfg, seed=3, object_set=object_set)
    try:
        first = json.dumps(scene_to_dict(a.generate(5)))
        b.generate(4)  # a different history must not matter
        assert json.dumps(scene_to_dict(b.generate(5))) == first
        assert json.dumps(scene_to_dict(a.generate(6))) != first
        assert scene_to_dict(scene_from_dict(json.loads(first))) == json.loads(first)
    finally:
        a.close()
        b.close()


def test_twenty_large_objects_fail_clearly_in_bounded_time(object_set):
    g = SceneGenerator({**BUILTIN, "min_objects": 20, "count_probabilities": [1.0], "stability": False, "layout_tries": 5,
                        "placement_tries": 40}, object_set=object_set)
    start = time.perf_counter()
    with pytest.raises(ConfigError, match="no valid layout in 5 tries.*placement"):
        g.generate(0)
    assert time.perf_counter() - start < 60
    g.close()


def test_margin_wider_than_the_table_is_refused_at_once(object_set):
    with pytest.raises(ConfigError, match="margin 2.0 m"):
        SceneGenerator({"margin": 2.0}, object_set=object_set)


def test_mistyped_option_names_the_valid_ones(object_set):
    with pytest.raises(ConfigError, match="min_visible_pixels"):
        SceneGenerator({"min_visible_pixel": 10}, object_set=object_set)


@pytest.mark.parametrize("option, value, words", [
    ("occlusion_scale", 1.5, r"occlusion_scale must be > 0 and <= 1, got 1\.5"),
    ("layout_tries", 0, "layout_tries must be >= 1, got 0"),
    ("min_objects", 0, "min_objects must be >= 1, got 0"),
    ("margin", -0.01, "margin must be >= 0, got -0.01"),
    ("camera_jitter_deg", -1.0, r"camera_jitter_deg must be >= 0 \(degrees, 0 = none\), got -1\.0"),
])
def test_out_of_range_options_are_refused_from_the_schemas_bounds(object_set, option, value, words):
    with pytest.raises(ConfigError, match=words):
        SceneGenerator({**BUILTIN, option: value}, object_set=object_set)


def test_the_images_are_the_renderers_size_and_layouts_settle_at_the_robots_step(object_set):
    """renderer.width/height size the scene's camera and masks, robot.timestep the settling: one setting each."""
    from muble.app.config import compose
    from muble.episode.components import scene_generator

    cfg = compose("run", ["dataset.root=/tmp", "output.dir=/tmp", "renderer.width=424", "renderer.height=240",
                          "robot.timestep=0.001"])
    g = scene_generator(cfg, object_set)
    try:
        assert g.timestep == 0.001
        scene = g.generate(0)
    finally:
        g.close()
    assert (scene.camera_params["width"], scene.camera_params["height"]) == (424, 240)
    assert all(decode_mask(o.mask).shape == (240, 424) for o in scene.objects)


def test_a_stage_is_written_into_the_scene_and_its_table_bounds_placement(object_set):
    """generator.stage: each scene names its stage, the layout keeps to that stage's table (the original's is
    0.8 m wide), and the reach check builds the robot on it."""
    from muble.sim.env import TabletopEnv
    from muble.stage.table import STAGES

    g = SceneGenerator({**BUILTIN, "stage": "original"}, seed=5, object_set=object_set)
    try:
        (x0, x1), (y0, y1) = STAGES["original"].top
        assert list(g.config.table_x) == [x0, x1] and list(g.config.table_y) == [y0, y1] == [-0.4, 0.4]
        scene = g.generate(0)
    finally:
        g.close()
    assert scene.extra["stage"] == "original"
    models = dict(enumerate(_models(object_set, scene)))
    env = TabletopEnv(scene, models, visual=False)
    assert env.names.stage == "original"
    for obj in scene.objects:  # every object's footprint lies on the desk
        half = max(obj.bbox["x"], obj.bbox["y"]) / 2
        assert x0 < obj.position[0] - half and obj.position[0] + half < x1
        assert y0 < obj.position[1] - half and obj.position[1] + half < y1

    with pytest.raises(ConfigError, match=r"unknown stage 'stadium'.*\(from generator.stage"):
        SceneGenerator({**BUILTIN, "stage": "stadium"}, seed=5, object_set=object_set)

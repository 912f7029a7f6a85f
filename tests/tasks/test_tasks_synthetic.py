"""The synthetic scenes hold the registered object set's objects: one object vocabulary for training and the
benchmark (no catalogue or size table of their own)."""
from __future__ import annotations

import pytest

from muble.core import physical_properties
from muble_plugins.common import synthetic
from muble_plugins.learned import parser
from muble_plugins.objects.catalogue import SIZE_SCALES
from muble_plugins.objects.shopvrb2 import CATALOGUE

# A protocol whose training pool leaves two mug models and every red finish out (as shopvrb2_v2 holds models and
# finishes back for its unseen_objects split).
PROTOCOL = {"common": {"objects": {"exclude_finishes": ["red plastic"]}},
            "splits": {"train": {"objects": {"exclude_models": ["mug2", "mug3"]}}}}


@pytest.fixture(scope="module")
def scenes():
    return synthetic.sample_scenes(21, 60, properties=True)


def test_every_object_is_one_the_object_set_draws(scenes):
    for scene in scenes:
        for o in scene.objects:
            category = CATALOGUE[o.name]
            assert o.model in category.variants and o.shape == category.variants[o.model][0]
            finish = next(f for f in category.finishes if f.material == o.material)
            assert o.colour in finish.colours
            assert o.size in category.sizes and o.scale_factor == SIZE_SCALES[o.size]
            low, high = finish.weight_g
            scale = SIZE_SCALES[o.size] ** category.mass_exponent
            assert low * scale - 0.05 <= o.weight_gt <= high * scale + 0.05, (o.name, o.material, o.weight_gt)
            assert o.stiffness is not None and o.stiffness > 0
            assert (o.stackable, o.stack_base, o.pickupable) == (category.stackable, category.stack_base,
                                                                 category.pickupable)
    # A soda can weighs what the object set says (340-390 g), not the 110-130 g of the old second catalogue.
    cans = [o.weight_gt for s in scenes for o in s.objects if o.name == "soda can"]
    assert cans and min(cans) >= 340 - 0.05 and max(cans) <= 390 + 0.05


def test_extents_and_hidden_properties_are_the_models_and_the_generators(scenes):
    objects = synthetic.object_set()
    for scene in scenes:
        for o in scene.objects:
            carried = physical_properties.SCENE_KEYS
            closed = CATALOGUE[o.name].closed
            has = {name for name, key in carried.items() if key in o.extra}
            if not o.pickupable:
                assert has == set()
            else:
                assert has == ({"friction", "com_offset", "contents"} if closed else {"friction", "com_offset"})
    # The bounding box is the built model's extents for that model and scale.
    o = scenes[0].objects[0]
    from muble.core.objects import ObjectSpec

    model = objects.build(ObjectSpec(object_set="shopvrb2", category=o.name, model=o.model, colour=o.colour,
                                     material=o.material, size=o.size, shape=o.shape, scale=o.scale_factor,
                                     weight_g=o.weight_gt, stiffness=o.stiffness))
    assert [o.bbox[k] for k in "xyz"] == pytest.approx([float(e) for e in model.extents])


def test_there_is_no_second_catalogue_or_size_table():
    assert not hasattr(synthetic, "CATEGORIES") and not hasattr(synthetic, "CLOSED")
    import inspect

    for module in (synthetic, parser):
        source = inspect.getsource(module)
        assert '"small": 0.8' not in source and "nominal" not in source, module.__name__


def test_a_protocols_training_pool_draws_no_held_out_model_or_finish():
    pool = synthetic.object_set(PROTOCOL)
    assert pool is synthetic.object_set(PROTOCOL)  # one instance per set and options: its geometry cache is kept
    seen = [o for s in synthetic.sample_scenes(4, 80, objects=pool) for o in s.objects]
    assert not [o.model for o in seen if o.model in ("mug2", "mug3")]
    assert not [o for o in seen if (o.colour, o.material) == ("red", "plastic")]
    assert any(o.model == "mug1" for o in seen)
    # The parser's scenes are the same scenes.
    rng_a, rng_b = (synthetic.streams.stream(synthetic.SCENE_STREAM, 3, 0) for _ in range(2))
    a = parser.sample_scene(pool, rng_a, 0)
    b = synthetic.sample_scene(rng_b, 0, n_objects=parser.OBJECTS_PER_SCENE, objects=pool)
    assert [(o.model, o.colour, o.weight_gt, o.bbox) for o in a.objects] == \
        [(o.model, o.colour, o.weight_gt, o.bbox) for o in b.objects]


def test_another_object_set_with_a_protocol_is_a_config_error():
    from muble.core.errors import ConfigError

    with pytest.raises(ConfigError, match="train without protocol"):
        synthetic.object_set(PROTOCOL, "ycb")


def test_a_full_table_starts_the_scene_over_and_too_many_objects_are_a_config_error():
    from muble.core.errors import ConfigError

    # Scene 1598 of the parser's data for seed 2 on shopvrb2_v2's training pool filled its table before its 7th
    # object (big boards and trays), and drew objects for ever.
    import numpy as np

    rng = np.random.default_rng(0)
    scene = synthetic.sample_scene(rng, 0, n_objects=(7, 7))
    assert len(scene.objects) == 7
    with pytest.raises(ConfigError, match="ask for fewer objects"):
        synthetic.sample_scene(np.random.default_rng(1), 0, n_objects=(80, 80))

"""Hidden physical properties in generated scenes: drawn per object from streams of their own, only for the objects
the object set says carry them, within their ranges, into the file and the built models; nothing else changes."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from muble import ConfigError, get_registry
from muble.core.physical_properties import (COM_OFFSET, COM_RADIUS_SHARE, CONTENTS, CONTENTS_G, CONTENTS_SHARE,
                                            FRICTION, FRICTION_RANGE, PROPERTIES, SCENE_KEYS)
from muble.generation import SceneGenerator, checks
from muble.io.scene_io import scene_from_dict, scene_to_dict
from muble.sim.build import object_models
from muble.stage.layout import Placement
from tests.generation.builtin import BUILTIN

pytestmark = pytest.mark.gl

FAST = {**BUILTIN, "stability": False, "reach_check": False}
ALL = {**FAST, "physical_properties": list(PROPERTIES)}
INDICES = range(6)


@pytest.fixture(scope="module")
def scenes(object_set):
    """Scenes 0-5 of seed 4 without the properties and with all three."""
    plain = SceneGenerator(FAST, seed=4, object_set=object_set)
    drawn = SceneGenerator(ALL, seed=4, object_set=object_set)
    try:
        yield [(plain.generate(i), drawn.generate(i)) for i in INDICES]
    finally:
        plain.close()
        drawn.close()


def _carried(object_set, obj) -> tuple[str, ...]:
    return object_set.physical_properties(object_set.spec_from_scene_object(obj))


def test_properties_are_drawn_for_the_objects_that_carry_them_within_their_ranges(object_set, scenes):
    seen = {"none": 0, "empty": 0, "contents": 0}
    for _, scene in scenes:
        for obj in scene.objects:
            carried = _carried(object_set, obj)
            # The carried ones only, in PROPERTIES order.
            assert list(obj.extra) == [SCENE_KEYS[p] for p in PROPERTIES if p in carried], (obj.name, obj.extra)
            if not carried:
                seen["none"] += 1
                continue
            mu = obj.extra[FRICTION]
            assert FRICTION_RANGE[0] <= mu <= FRICTION_RANGE[1] and round(mu, 3) == mu
            offset = obj.extra[COM_OFFSET]
            radius = COM_RADIUS_SHARE * min(obj.bbox["x"], obj.bbox["y"])
            assert len(offset) == 2 and np.hypot(*offset) <= radius + 1e-4
            assert [round(v, 4) for v in offset] == offset
            if "contents" in carried:
                grams = obj.extra[CONTENTS]
                if grams == 0.0:
                    seen["empty"] += 1
                else:
                    seen["contents"] += 1
                    assert min(CONTENTS_G[0], CONTENTS_SHARE * obj.weight_gt) - 0.05 <= grams
                    assert grams <= min(CONTENTS_G[1], CONTENTS_SHARE * obj.weight_gt) + 0.05
                    assert round(grams, 1) == grams
    # The scenes hold objects of each kind, so every branch above was checked.
    assert all(seen.values()), seen
    # SHOP-VRB2: the pickupable categories carry friction and a centre of mass, the closed ones among them contents.
    spec = object_set.sample(np.random.default_rng(0), "soda can")
    assert object_set.physical_properties(spec) == ("friction", "com_offset", "contents")
    assert object_set.physical_properties(object_set.sample(np.random.default_rng(0), "mug")) == ("friction",
                                                                                                  "com_offset")
    assert object_set.physical_properties(object_set.sample(np.random.default_rng(0), "food box")) == ()
    ycb = get_registry().create("object_set", "ycb")
    assert all(ycb.physical_properties(ycb.sample(np.random.default_rng(0), c)) == () for c in ycb.categories())


def test_enabling_them_leaves_every_other_byte_of_the_scene(scenes):
    for plain, drawn in scenes:
        assert all(o.extra == {} for o in plain.objects)
        stripped = scene_to_dict(drawn)
        for o in stripped["objects"]:
            for key in SCENE_KEYS.values():
                o.pop(key, None)
        assert json.dumps(stripped) == json.dumps(scene_to_dict(plain))


def test_same_seed_same_values_and_each_property_has_its_own_stream(object_set, scenes):
    again = SceneGenerator({**FAST, "physical_properties": list(reversed(PROPERTIES))}, seed=4, object_set=object_set)
    friction_only = SceneGenerator({**FAST, "physical_properties": ["friction"]}, seed=4, object_set=object_set)
    other_seed = SceneGenerator(ALL, seed=5, object_set=object_set)
    try:
        for index in (0, 1):
            _, drawn = scenes[index]
            # The order asked in does not matter: the file's keys and values are the same.
            assert json.dumps(scene_to_dict(again.generate(index))) == json.dumps(scene_to_dict(drawn))
            alone = friction_only.generate(index)
            assert [o.extra.get(FRICTION) for o in alone.objects] == [o.extra.get(FRICTION) for o in drawn.objects]
            assert all(set(o.extra) <= {FRICTION} for o in alone.objects)
        values = [o.extra.get(FRICTION) for o in other_seed.generate(0).objects]
        assert values != [o.extra.get(FRICTION) for o in scenes[0][1].objects]
    finally:
        for g in (again, friction_only, other_seed):
            g.close()


def test_the_file_and_the_built_environment_carry_them(object_set, scenes):
    for _, scene in scenes:
        back = scene_from_dict(json.loads(json.dumps(scene_to_dict(scene))))
        assert [o.extra for o in back.objects] == [o.extra for o in scene.objects]
        models = object_models(back, object_set, "shopvrb2")
        for obj in back.objects:
            model = models[obj.id]
            assert model.friction_coefficient == obj.extra.get(FRICTION)
            assert (None if model.com_offset is None else list(model.com_offset)) == obj.extra.get(COM_OFFSET)
            assert model.contents_mass == pytest.approx((obj.extra.get(CONTENTS) or 0.0) / 1000.0)
            assert model.mass == pytest.approx(obj.weight_gt / 1000.0)  # the contents are part of the weight


def test_every_check_sees_the_models_the_file_describes(object_set):
    seen = []

    def reach(scene, models):  # the last check: it gets the models every check before it had
        seen.append((scene, models))
        return None

    generator = SceneGenerator({**ALL, "stability": True}, seed=4, object_set=object_set, reach_check=reach)
    try:
        scene = generator.generate(0)  # a thermos and a soda can with contents
    finally:
        generator.close()
    checked, models = seen[-1]
    assert checked is scene
    built = object_models(scene, object_set, "shopvrb2")
    for obj in scene.objects:
        for field in ("friction_coefficient", "contents_mass", "closed"):
            assert getattr(models[obj.id], field) == getattr(built[obj.id], field), (obj.id, field)
        assert np.array_equal(models[obj.id].centre_of_mass, built[obj.id].centre_of_mass)
    assert any(m.contents_mass > 0 for m in models.values()) and any(m.com_offset is not None for m in models.values())


def test_a_container_with_loose_contents_stacks_as_an_empty_one_does(object_set):
    rng = np.random.default_rng(3)
    plate = object_set.build(object_set.sample(rng, "plate"))
    can = object_set.build(object_set.sample(rng, "soda can"))
    full = dataclasses.replace(can, contents_mass=0.03)
    placements = [Placement(0.45, -0.15, 0.0), Placement(0.55, 0.1, 0.0)]
    for top in (can, full):
        # Its own contents, inside its walls all the way down, are not in its way.
        assert checks.stacks_stand([plate, top], placements, [(1, 0)], [0.16, 1.06], [-0.6, 0.6], 0.002) is None


def test_an_unknown_property_names_the_valid_ones(object_set):
    with pytest.raises(ConfigError, match=r"unknown generator.physical_properties property 'mass'.*"
                                          r"com_offset, contents, friction"):
        SceneGenerator({**FAST, "physical_properties": ["friction", "mass"]}, object_set=object_set)

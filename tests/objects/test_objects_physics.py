"""Drop, stack and containment tests with real MuJoCo physics (acceptance of the object sets)."""
import numpy as np
import pytest

from muble_plugins.objects.shopvrb2 import CATALOGUE
from muble_plugins.objects.ycb import CATALOGUE as YCB
from tests.support.object_checks import drop, settle, stack

from muble_plugins.objects.testing import spec_of

SHOP_MODELS = [(c, m) for c in sorted(CATALOGUE) for m in CATALOGUE[c].variants]


def _assert_rests_upright(report, index=0):
    assert report.penetration <= 0.002
    assert report.speed[index] < 0.001
    assert report.tilt_deg[index] < 2.0


@pytest.mark.parametrize("category,model", SHOP_MODELS)
def test_objects_shopvrb2_drop_rests_upright(shopvrb2, category, model):
    report = drop(shopvrb2.build(spec_of(shopvrb2, category, model)), height=0.05, seconds=2.0)
    _assert_rests_upright(report)
    assert abs(report.positions[0, 2]) < 0.002  # the base sits on the table top (z = 0)


@pytest.mark.parametrize("category", sorted(YCB))
def test_objects_ycb_drop_rests_upright(ycb, category):
    report = drop(ycb.build(ycb.sample(np.random.default_rng(0), category)))
    _assert_rests_upright(report)


STACKABLE = sorted(c for c in CATALOGUE if CATALOGUE[c].stackable)
BASES = sorted(c for c in CATALOGUE if CATALOGUE[c].stack_base)


@pytest.mark.parametrize("top", STACKABLE)
@pytest.mark.parametrize("base", BASES)
def test_objects_stackable_on_base_rests(shopvrb2, base, top):
    base_model = shopvrb2.build(spec_of(shopvrb2, base, next(iter(CATALOGUE[base].variants)), "large"))
    top_model = shopvrb2.build(spec_of(shopvrb2, top, next(iter(CATALOGUE[top].variants)), "small"))
    report = stack(base_model, top_model)
    assert report.penetration <= 0.002
    assert np.all(report.speed < 0.001)
    # The top object rests on the base, not on the table, within the base's footprint.
    assert (0, 1) in report.touching and (-1, 1) not in report.touching
    assert np.all(np.abs(report.positions[1, :2]) < base_model.extents[:2] / 2)


def test_objects_bowl_holds_a_small_object(shopvrb2):
    bowl = shopvrb2.build(spec_of(shopvrb2, "bowl", "bowl1", "large"))
    can = shopvrb2.build(spec_of(shopvrb2, "glass", "glass3", "small"))
    # Dropped off-centre from above the rim: it must end up inside, on the bowl's floor or wall.
    report = settle([(bowl, (0, 0, 0), (1, 0, 0, 0)), (can, (0.02, 0.01, bowl.extents[2] + 0.01), (1, 0, 0, 0))])
    assert (0, 1) in report.touching and (-1, 1) not in report.touching
    assert np.hypot(*report.positions[1, :2]) < bowl.extents[0] / 2
    assert report.positions[1, 2] < bowl.extents[2]  # its base is below the rim: inside, not balanced on top
    assert np.all(report.speed < 0.001)

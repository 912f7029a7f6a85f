"""Object sets through the registry and Hydra: selection, validation, sampling, determinism, caching."""
import numpy as np
import pytest

from muble import ConfigError, get_registry
from muble.app.config import compose
from muble.core.objects import GRASP_TYPES, MATERIAL_CLASSES
from muble_plugins.objects.catalogue import COLOUR_RGBA, MeshCache
from muble_plugins.objects.shopvrb2 import ShopVrb2Objects

SHOP_CATEGORIES = ["baking tray", "bowl", "chopping board", "food box", "glass", "mug", "plate", "soda can",
                   "thermos", "wine glass"]


pytestmark = pytest.mark.usefixtures("clear_hydra")


@pytest.mark.parametrize("name", ["shopvrb2", "ycb"])
def test_objects_selectable_by_config(name):
    cfg = compose(config_name=None, overrides=[f"+objects={name}"])
    assert cfg.objects.name == name
    params = {k: v for k, v in cfg.objects.items() if k != "name"}
    objects = get_registry().create("object_set", name, params)
    spec = objects.sample(np.random.default_rng(0))
    assert spec.object_set == name and spec.category in objects.categories()


def test_objects_config_rejects_mistyped_key():
    with pytest.raises(Exception, match="categorys"):
        compose(config_name=None, overrides=["+objects=shopvrb2", "objects.categorys=[mug]"])


def test_objects_unknown_category_lists_valid_ones(shopvrb2):
    with pytest.raises(ConfigError) as err:
        shopvrb2.sample(np.random.default_rng(0), "teapot")
    assert "teapot" in str(err.value) and all(c in str(err.value) for c in SHOP_CATEGORIES)
    with pytest.raises(ConfigError, match="wine glass"):
        ShopVrb2Objects(cache_dir=None, categories=["wineglass"])


def test_objects_shopvrb2_vocabulary_and_realistic_combinations(shopvrb2):
    assert shopvrb2.categories() == SHOP_CATEGORIES
    rng = np.random.default_rng(3)
    for _ in range(300):
        spec = shopvrb2.sample(rng)
        assert spec.size in ("small", "medium-sized", "large") and spec.colour in COLOUR_RGBA
        assert spec.material in ("plastic", "metal", "glass", "rubber", "wooden", "ceramic")
        assert (spec.material == "glass") == (spec.colour == "transparent")
        assert not (spec.category in ("wine glass", "glass", "soda can") and spec.material == "wooden")
        assert 20 < spec.weight_g < 1500 and spec.stiffness > 0
    model = shopvrb2.build(shopvrb2.sample(rng, "wine glass"))
    assert model.material_class in MATERIAL_CLASSES and model.grasp_type in GRASP_TYPES
    assert model.uv is not None and model.uv.shape == (len(model.visual.vertices), 2)


def test_objects_real_sizes(shopvrb2):
    from muble_plugins.objects.testing import spec_of

    mug = shopvrb2.build(spec_of(shopvrb2, "mug", "mug1"))
    assert 0.075 <= mug.extents[1] <= 0.085 and 0.09 <= mug.extents[2] <= 0.105  # body 8 cm wide, 9.5 cm tall
    plate = shopvrb2.build(spec_of(shopvrb2, "plate", "plate1"))
    assert 0.24 <= plate.extents[0] <= 0.27
    assert len(mug.collision_parts) > 10 and mug.grasp_type == "handle"


def test_objects_generation_is_deterministic_and_cached(tmp_path):
    first = ShopVrb2Objects(cache_dir=str(tmp_path))
    spec = first.sample(np.random.default_rng(11), "bowl")
    assert spec == ShopVrb2Objects(cache_dir=None).sample(np.random.default_rng(11), "bowl")
    cold = first.build(spec)
    assert len(list(tmp_path.glob("*.npz"))) == 1
    warm = ShopVrb2Objects(cache_dir=str(tmp_path)).build(spec)
    uncached = ShopVrb2Objects(cache_dir=None).build(spec)
    for other in (warm, uncached):
        assert np.array_equal(cold.visual.vertices, other.visual.vertices)
        assert len(cold.collision_parts) == len(other.collision_parts)
        assert np.allclose(cold.inertia, other.inertia) and cold.mass == other.mass
    assert MeshCache.key("shopvrb2", "bowl1", 1.0, {}) != MeshCache.key("shopvrb2", "bowl1", 0.85, {})

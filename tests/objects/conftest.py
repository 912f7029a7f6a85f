import numpy as np
import pytest

from muble_plugins.objects.shopvrb2 import ShopVrb2Objects
from muble_plugins.objects.ycb import YcbObjects


@pytest.fixture(scope="session")
def shopvrb2(tmp_path_factory):
    return ShopVrb2Objects(cache_dir=str(tmp_path_factory.mktemp("object_cache")))


@pytest.fixture(scope="session")
def ycb(tmp_path_factory):
    return YcbObjects(cache_dir=str(tmp_path_factory.mktemp("ycb_cache")))


def spec_of(objects, category, model, size="medium-sized", seed=0):
    """A sampled spec of ``category`` forced to ``model`` and ``size`` (weight kept in its sampled range)."""
    from muble_plugins.objects.catalogue import SIZE_SCALES

    spec = objects.sample(np.random.default_rng(seed), category)
    cat = objects.catalogue[category]
    factor = (SIZE_SCALES[size] / spec.scale) ** cat.mass_exponent
    spec.model, spec.shape = model, cat.variants[model][0]
    spec.size, spec.scale = size, SIZE_SCALES[size]
    spec.weight_g = round(spec.weight_g * factor, 1)
    return spec

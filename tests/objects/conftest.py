import pytest

from muble_plugins.objects.shopvrb2 import ShopVrb2Objects
from muble_plugins.objects.ycb import YcbObjects


@pytest.fixture(scope="session")
def shopvrb2(tmp_path_factory):
    return ShopVrb2Objects(cache_dir=str(tmp_path_factory.mktemp("object_cache")))


@pytest.fixture(scope="session")
def ycb(tmp_path_factory):
    return YcbObjects(cache_dir=str(tmp_path_factory.mktemp("ycb_cache")))

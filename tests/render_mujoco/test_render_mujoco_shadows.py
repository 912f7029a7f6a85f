"""The MuJoCo renderer's shadow options: turning shadows off or shrinking the maps changes the RGB image only."""
from __future__ import annotations

import numpy as np
import pytest

from muble import SEG_TABLE, ConfigError, get_registry

pytestmark = pytest.mark.gl


def _frame(env, **options):
    renderer = get_registry().create("renderer", "mujoco", options)
    try:
        renderer.setup(env.sync_scene_graph(), env.model)
        return renderer.render(env.data, env.names.cameras["front"])
    finally:
        renderer.close()


def _changed(a, b) -> float:
    return float((np.abs(a.rgb.astype(np.int16) - b.rgb.astype(np.int16)).max(axis=2) > 0).mean())


def test_shadow_options_change_the_rgb_only(generated_env):
    default = _frame(generated_env, shadow_size=None)  # the model's own 4096² maps
    unshadowed = _frame(generated_env, shadows=False)
    small_maps = _frame(generated_env)  # the renderer's default, 1024² maps
    for other in (unshadowed, small_maps):
        np.testing.assert_array_equal(other.segmentation, default.segmentation)
        np.testing.assert_array_equal(other.depth, default.depth)
    # Without shadows every shadow-casting light reaches the whole table: no table pixel darker, the table
    # brighter on the whole, and most pixels of the frame change.
    table = default.mask(SEG_TABLE)
    lit, shaded = unshadowed.rgb[table].astype(np.int16), default.rgb[table].astype(np.int16)
    assert (lit >= shaded).all(axis=1).mean() > 0.99
    assert lit.mean() > shaded.mean() + 2
    assert _changed(default, unshadowed) > 0.3
    # Smaller maps reach the context (shadow edges move) and leave the rest of the frame as it was.
    assert 0 < _changed(default, small_maps) < 0.01
    # The environment's model keeps its own shadow maps for whoever renders it next.
    assert generated_env.model.vis.quality.shadowsize == 4096
    np.testing.assert_array_equal(_frame(generated_env, shadow_size=None).rgb, default.rgb)


def test_shadow_size_out_of_range_is_refused():
    with pytest.raises(ConfigError, match="shadow_size must be 64..16384"):
        get_registry().create("renderer", "mujoco", {"shadow_size": 16})

"""The in-memory build cache: cached builds carry the same physics as a fresh integration of the geometry."""
from __future__ import annotations

import numpy as np
import pytest

from muble_plugins.objects.geometry import mass_properties


def _spec(shopvrb2, weight_g: float):
    spec = shopvrb2.sample(np.random.default_rng(3), category="mug")
    spec.weight_g = weight_g
    return spec


def test_cached_builds_match_fresh_mass_properties(shopvrb2):
    light = shopvrb2.build(_spec(shopvrb2, 150.0))
    heavy = shopvrb2.build(_spec(shopvrb2, 450.0))  # same model and scale: served from the cache
    assert heavy.visual.vertices is light.visual.vertices
    for model in (light, heavy):
        com, inertia = mass_properties(model.collision_parts, model.mass)
        np.testing.assert_allclose(model.com, com, atol=1e-12)
        np.testing.assert_allclose(model.inertia, inertia, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(heavy.inertia, 3.0 * light.inertia, rtol=1e-12)
    assert heavy.mass == pytest.approx(0.45)


def test_shared_meshes_are_read_only(shopvrb2):
    model = shopvrb2.build(_spec(shopvrb2, 200.0))
    with pytest.raises(ValueError):
        model.visual.vertices[0, 0] = 1.0
    model.com[0] += 1.0  # per-build arrays stay private to the build
    assert shopvrb2.build(_spec(shopvrb2, 200.0)).com[0] != model.com[0]


def test_wrong_category_is_still_refused_after_a_cached_build(shopvrb2):
    from muble import ConfigError

    spec = _spec(shopvrb2, 200.0)
    shopvrb2.build(spec)
    spec.category = "bowl"  # the mug model under another category
    with pytest.raises(ConfigError):
        shopvrb2.build(spec)

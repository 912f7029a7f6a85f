"""A closed renderer's GL context is kept and reused; frames drawn in it equal frames from a fresh context."""
from __future__ import annotations

import numpy as np
import pytest

import muble_plugins.renderers.mujoco.gl as gl
from muble import get_registry
from muble_plugins.renderers.render_world import build_world, random_scene

pytestmark = pytest.mark.gl


def _frame(scene_seed: int):
    scene = random_scene(np.random.default_rng(scene_seed), n_objects=3)
    model, data = build_world(scene, arm_seed=scene_seed)  # robosuite's lights, shadows and reflections
    renderer = get_registry().create("renderer", "mujoco", {"width": 424, "height": 240})
    renderer.setup(scene, model)
    try:
        return renderer.render(data, "frontview"), renderer._gl
    finally:
        renderer.close()


def test_reused_context_draws_the_same_pixels(monkeypatch):
    monkeypatch.setattr(gl, "MAX_SPARE", 0)
    gl.free_spares()
    fresh = [_frame(seed)[0] for seed in (1, 2)]
    monkeypatch.setattr(gl, "MAX_SPARE", 2)
    first, context = _frame(1)
    second, reused = _frame(2)
    assert reused is context  # the second renderer drew in the first one's context
    for a, b in zip(fresh, (first, second)):
        assert np.array_equal(a.rgb, b.rgb)
        assert np.array_equal(a.segmentation, b.segmentation)
        assert np.array_equal(a.depth, b.depth)
    gl.free_spares()

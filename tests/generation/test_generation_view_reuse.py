"""The re-posed render model draws the same labels as a model compiled for the layout alone."""
from __future__ import annotations

import numpy as np
import pytest

from muble import get_registry
from muble.generation import SceneGenerator, checks
from muble.generation.contact_sheet import models_from_scene, placements_from_scene
from muble.generation.placement import CollisionMesh, min_pairwise_distance, shared_collision_meshes
from tests.generation.builtin import BUILTIN

pytestmark = pytest.mark.gl


def test_reposed_view_matches_a_freshly_compiled_one():
    object_set = get_registry().create("object_set", "shopvrb2")
    gen = SceneGenerator({**BUILTIN, "stability": False}, seed=5, object_set=object_set)
    fresh = get_registry().create("renderer", "mujoco", {"width": 848, "height": 480, "rgb": False,
                                                         "depth": False, "segmentation": True})
    try:
        for index in (0, 1, 2):  # later scenes re-pose a view that already holds other meshes
            scene = gen.generate(index)
            models, placements = models_from_scene(object_set, scene), placements_from_scene(scene)
            reposed = gen._draw(gen.renderer, models, placements).segmentation
            view, data = checks.view_model(models, placements, gen.camera, gen.config.table_x, gen.config.table_y)
            fresh.setup(None, view)
            compiled = fresh.render(data, checks.CAMERA_NAME).segmentation
            assert np.mean(reposed == compiled) > 0.999
            for i in range(len(models)):
                a, b = (reposed == i).sum(), (compiled == i).sum()
                assert a >= gen.config.min_visible_pixels and abs(a - b) <= 0.01 * b
            # cached BVHs give the distances of freshly built ones
            cached = [shared_collision_meshes().get(m) for m in models]
            assert min_pairwise_distance(cached, placements) == pytest.approx(
                min_pairwise_distance([CollisionMesh(m) for m in models], placements), abs=1e-12)
    finally:
        fresh.close()
        gen.close()

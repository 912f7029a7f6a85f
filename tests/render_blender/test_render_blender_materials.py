"""Material classes are measurably distinct; scene data does not pile up between scenes."""
import itertools

import numpy as np
import pytest

from muble import ConfigError
from muble_plugins.renderers.blender import BlenderRenderer
from muble_plugins.renderers.blender.appearance import appearance, appearance_distance, luma
from muble_plugins.renderers.render_world import MATERIALS, build_world, glass_slab_rig, material_rig, random_scene

pytestmark = pytest.mark.blender


def rig_frame(width: int, height: int):
    """The material rig seen by its camera at 8 samples."""
    scene, model, data = material_rig()
    renderer = BlenderRenderer(width=width, height=height, samples=8)
    try:
        renderer.setup(scene, model)
        return renderer.render(data, "materials")
    finally:
        renderer.close()


def test_each_material_class_looks_different():
    frame = rig_frame(240, 120)
    looks = {name: appearance(frame.rgb, frame.mask(i)) for i, name in enumerate(MATERIALS)}
    for a, b in itertools.combinations(MATERIALS, 2):
        assert appearance_distance(looks[a], looks[b]) > 0.25, (a, looks[a], b, looks[b])
    # The physical signatures of the recipes, not just "different".
    assert looks["metal"]["highlight"] > looks["plastic"]["highlight"] > looks["rubber"]["highlight"]
    assert looks["glass"]["saturation"] < looks["plastic"]["saturation"]  # mostly shows what is behind it
    assert looks["wood"]["texture"] > 1.5 * looks["plastic"]["texture"]  # grain


def test_the_table_grain_runs_along_the_table():
    # The rig's camera looks along the table's y axis, so a grain running along x (the desk's boards) makes the
    # luma change from row to row and hardly from column to column; a figure without a direction would not.
    from scipy import ndimage

    from muble.core.types import SEG_TABLE

    frame = rig_frame(480, 240)
    y = luma(frame.rgb)
    table = ndimage.binary_erosion(frame.mask(SEG_TABLE), iterations=2)
    across = np.abs(np.diff(y, axis=0))[table[1:] & table[:-1]].mean()  # row to row: across the grain
    along = np.abs(np.diff(y, axis=1))[table[:, 1:] & table[:, :-1]].mean()
    assert table.sum() > 5000
    assert across > 2.0 * along, (across, along)


def test_scene_changes_leave_no_blender_data_behind():
    import bpy

    renderer = BlenderRenderer(width=64, height=48, samples=1, denoise=False)

    def counts():
        return {kind: len(getattr(bpy.data, kind)) for kind in
                ("objects", "meshes", "materials", "lights", "cameras", "worlds", "images", "node_groups")}

    try:
        seen = []
        for seed in range(4):
            scene = random_scene(np.random.default_rng(seed), n_objects=2 + seed % 3, image_index=seed)
            model, data = build_world(scene, arm_seed=seed)
            renderer.setup(scene, model)
            renderer.render(data, "frontview")
            seen.append(counts())
        # Scenes 0 and 3 both have two objects: the same data blocks, not more.
        assert seen[3] == seen[0]
    finally:
        renderer.close()


def test_options_are_checked():
    with pytest.raises(ConfigError, match="valid options"):
        BlenderRenderer(sampels=4)
    with pytest.raises(ConfigError, match="valid render engine names: BLENDER_EEVEE, CYCLES"):
        BlenderRenderer(engine="EEVEE_NEXT")


def test_a_glass_standing_on_the_table_shows_the_table_through_its_base():
    # A glass slab resting on the table has its base in the table's top face. Rays leaving the base there used to
    # be lost between the coplanar faces, so the glass stood in a dark pool; the table seen through it should be
    # about as bright as beside it (a clear glass passes most light).
    from muble.core.types import SEG_TABLE

    scene, model, data = glass_slab_rig()
    renderer = BlenderRenderer(width=160, height=120, samples=8)
    try:
        renderer.setup(scene, model)
        frame = renderer.render(data, "above")
    finally:
        renderer.close()
    from scipy import ndimage

    y = luma(frame.rgb)
    glass = ndimage.binary_erosion(frame.mask(0), iterations=3)
    table = ndimage.binary_erosion(frame.mask(SEG_TABLE), iterations=3)
    assert glass.sum() > 500 and table.sum() > 2000
    assert np.median(y[glass]) > 0.7 * np.median(y[table]), (np.median(y[glass]), np.median(y[table]))

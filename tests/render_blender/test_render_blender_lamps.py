"""The scene file's lamps light the Blender scene where the file puts them, each with its role's power."""
from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.blender

LAMPS = {"Lamp_Key": [3.2, -2.1, 2.2], "Lamp_Back": [-1.8, 2.0, 2.3], "Lamp_Fill": [-2.4, -3.0, 2.5]}


def test_lamp_params_place_key_fill_and_back():
    import bpy
    from mathutils import Vector

    from muble_plugins.renderers.blender.config import BlenderRendererConfig
    from muble_plugins.renderers.blender.stage import LAMP_ROLES, build_scene_lamps

    scene = bpy.data.scenes.new("lamps_test")
    try:
        target = np.array([0.0, 0.0, 0.8])
        lights = build_scene_lamps(scene.collection, LAMPS, target, BlenderRendererConfig())
        by_name = {light.name: light for light in lights}
        assert set(by_name) == {"muble_lamp_key", "muble_lamp_back", "muble_lamp_fill"}
        for name, position in LAMPS.items():
            light = by_name[f"muble_{name.lower()}"]
            assert np.allclose(light.location, position)
            aim = light.rotation_euler.to_matrix() @ Vector((0, 0, -1))
            towards = (target - np.array(position)) / np.linalg.norm(target - np.array(position))
            assert np.dot(np.array(aim), towards) > 0.999  # area lights shine down their -Z
            role = name.split("_")[1].lower()
            irradiance = light.data.energy / np.linalg.norm(target - np.array(position)) ** 2
            assert irradiance == pytest.approx(LAMP_ROLES[role][0])
        assert by_name["muble_lamp_key"].data.energy > by_name["muble_lamp_fill"].data.energy
    finally:
        for obj in list(scene.collection.objects):
            data = obj.data
            bpy.data.objects.remove(obj, do_unlink=True)
            bpy.data.lights.remove(data)
        bpy.data.scenes.remove(scene)


def test_the_room_casts_no_shadow_from_the_scene_lamps(generated_env):
    """The scene file's lamps stand where the original's stood, outside robosuite's room: by the lamps' direct
    light alone (no bounces, no sky) the table is as bright with the floor and the walls drawn as with no world
    geometry at all (walls that cast shadows left it at less than half)."""
    import mujoco

    from muble.core.types import SEG_TABLE
    from muble_plugins.renderers.blender import BlenderRenderer

    env = generated_env
    assert env.scene.lamp_params
    camera = env.names.cameras["front"]
    brightness = {}
    for name, world in (("none", dict(floor=False)), ("room", dict(floor=True, walls=True))):
        # No sky and no studio backdrop (which the table's varnish would reflect where the walls do not hide it).
        renderer = BlenderRenderer(width=212, height=120, samples=16, denoise=False, max_bounces=0,
                                   exposure=0.0, background_strength=0.0, backdrop="sky", **world)
        try:
            renderer.setup(env.sync_scene_graph(), env.model)
            if name == "room":
                assert any("wall" in env.model.geom(int(g)).name for g in renderer._geoms)
            frame = renderer.render(env.data, camera)
            brightness[name] = float(frame.rgb[frame.segmentation == SEG_TABLE].mean())
        finally:
            renderer.close()
    # The default draws the floor but not the room's walls.
    default = BlenderRenderer(width=212, height=120, samples=1, denoise=False)
    try:
        default.setup(env.sync_scene_graph(), env.model)
        world = [int(g) for g in default._geoms if env.model.geom_bodyid[int(g)] == 0]
        assert world and all(env.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE for g in world)
    finally:
        default.close()
    assert brightness["none"] > 40
    assert brightness["room"] == pytest.approx(brightness["none"], rel=0.05)

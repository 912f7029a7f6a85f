"""``muble render``: a scene file and an episode's keyframes to PNGs, a GIF and a contact sheet."""
import numpy as np
import pytest
from PIL import Image

from muble import ConfigError, SceneGraph, SceneObject, get_registry
from muble.app.render import main, renderer_options
from muble.io.image_grid import contact_sheet
from muble.io.scene_io import save_scene


def test_renderer_options_parse_yaml_values():
    assert renderer_options(["samples=8", "denoise=false", "table_rgb=[0.1, 0.2, 0.3]"]) == {
        "samples": 8, "denoise": False, "table_rgb": [0.1, 0.2, 0.3]}
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        renderer_options(["samples"])


def test_contact_sheet_tiles_in_rows():
    images = [np.full((30, 40, 3), 40 * i, dtype=np.uint8) for i in range(5)]
    sheet = contact_sheet(images, columns=3, width=80)
    assert sheet.shape == (2 * 60 + 3 * 4, 3 * 80 + 4 * 4, 3)
    assert sheet[4 + 60 + 4 + 30, 4 + 80 + 4 + 40].tolist() == [160, 160, 160]  # image 4: row 1, column 1


def _scene(rng) -> SceneGraph:
    object_set = get_registry().create("object_set", "shopvrb2")
    objects = []
    for i, xy in enumerate([(0.1, -0.1), (0.15, 0.12)]):
        spec = object_set.sample(rng)
        objects.append(SceneObject(
            id=i, model=spec.model, name=spec.category, shape=spec.shape, size=spec.size, material=spec.material,
            colour=spec.colour, position=np.array([*xy, 0.0]), orientation=np.array([1.0, 0, 0, 0]),
            weight_gt=spec.weight_g, stackable=False, stack_base=False, pickupable=True,
            scale_factor=spec.scale, stiffness=spec.stiffness, extra={"params": dict(spec.params)}))
    return SceneGraph(objects=objects, split="test")


@pytest.mark.blender
@pytest.mark.slow
def test_render_command_writes_keyframes_gif_and_sheet(tmp_path):
    scene_file = tmp_path / "scene.json"
    save_scene(scene_file, _scene(np.random.default_rng(3)))
    from muble.io.scene_io import load_scene
    from muble.sim.build import env_from_object_set

    env = env_from_object_set(load_scene(scene_file), "shopvrb2")
    env.reset()
    qpos = np.stack([env.data.qpos.copy(), env.data.qpos.copy()])
    qpos[1, :7] += 0.3  # the arm moves: the two keyframes differ
    env.close()
    np.savez(tmp_path / "episode.npz", qpos=qpos)
    out = tmp_path / "out"
    code = main([str(scene_file), "--keyframes", str(tmp_path / "episode.npz"), "--out", str(out), "--passes",
                 "--set", "width=96", "--set", "height=72", "--set", "samples=1", "--set", "denoise=false"])
    assert code == 0
    first, second = (np.asarray(Image.open(out / f"keyframe_000{k}.png")) for k in range(2))
    assert first.shape == (72, 96, 3) and np.abs(first.astype(int) - second).mean() > 1.0
    seg = np.asarray(Image.open(out / "keyframe_0000_seg.png"))
    assert {1, 3, 4} <= set(np.unique(seg).tolist())  # table and both objects seen by the front camera
    assert (out / "episode.gif").exists() and (out / "contact_sheet.png").exists()

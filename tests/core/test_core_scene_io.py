"""Scene files: lossless round-trips of the SHOP-VRB2 schema and specific errors for malformed input."""
from __future__ import annotations

import copy
import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from muble import SceneValidationError
from muble.io.scene_io import load_scene, load_scenes, save_scene, save_scenes, scene_from_dict, scene_to_dict


def make_scene_dict(n: int = 3) -> dict:
    """A small scene in the SHOP-VRB2 schema, written here (not copied from the release)."""
    objects = []
    for i in range(n):
        objects.append({
            "file": f"mug{i + 1}", "name": "mug", "shape": "cylindrical", "size": "small", "material": "ceramic",
            "3d_coords": [0.4 + 0.1 * i, -0.1 * i, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0], "rotation": 0.0,
            "pixel_coords": [100 + i, 200, 0.8], "colour": "red", "weight_gt": 250.0 + i, "weight": None,
            "movability": "portable", "bbox": {"x": 0.08, "y": 0.08, "z": 0.1}, "scale_factor": 0.5,
            "stackable": True, "stack_base": False, "pickupable": True,
            "mask": {"size": [48, 64], "counts": "PPYo0"},
        })
    return {
        "split": "test", "image_index": 7, "image_filename": "t_000007.png", "objects": objects,
        "directions": {"left": [0.0, -1.0, 0.0], "right": [0.0, 1.0, 0.0]},
        "camera_params": {"position": [1.1, 0.0, 0.2], "rotation": [83.0, 0.0, 90.0], "rotation_mode": "EulerXYZ"},
        "lamp_params": {"Lamp_Key": [3.0, -2.0, 2.0]},
        "table": {"mask": {"size": [48, 64], "counts": "PPYo0"}},
        "robot": {"mask": {"size": [48, 64], "counts": "PPYo0"}},
        "relationships": {"left": [[], [0], [0, 1]], "right": [[1, 2], [2], []]},
    }


def test_own_fixture_round_trips(tmp_path):
    d = make_scene_dict()
    scene = scene_from_dict(d)
    assert [o.id for o in scene.objects] == [0, 1, 2]
    assert scene.objects[1].weight_gt == 251.0
    assert scene_to_dict(scene) == d
    save_scene(tmp_path / "s.json", scene)
    assert json.loads((tmp_path / "s.json").read_text()) == d


@pytest.mark.parametrize("name", ["NS_AP_demo_000000.json", "NS_AP_demo_000001.json", "NS_AP_demo_000002.json"])
def test_reference_single_scene_round_trips(reference_dir, tmp_path, name):
    original = json.loads((reference_dir / name).read_text())
    scene = load_scene(reference_dir / name)
    assert scene_to_dict(scene) == original
    save_scene(tmp_path / name, scene)
    assert json.loads((tmp_path / name).read_text()) == original
    assert all(o.mask is not None for o in scene.objects)  # COCO RLE kept as data


def test_reference_combined_file_round_trips(reference_dir, tmp_path):
    original = json.loads((reference_dir / "NS_AP_demo_scenes.json").read_text())
    info, scenes = load_scenes(reference_dir / "NS_AP_demo_scenes.json")
    assert len(scenes) == 10 and info == original["info"]
    save_scenes(tmp_path / "all.json", scenes, info)
    assert json.loads((tmp_path / "all.json").read_text()) == original


def _broken(mutate) -> dict:
    d = make_scene_dict()
    mutate(d)
    return d


@pytest.mark.parametrize(
    ("mutate", "obj", "field"),
    [
        (lambda d: d["objects"][1].pop("weight_gt"), 1, "weight_gt"),
        (lambda d: d["objects"][0].pop("3d_coords"), 0, "3d_coords"),
        (lambda d: d["objects"][2].__setitem__("weight_gt", "heavy"), 2, "weight_gt"),
        (lambda d: d["objects"][0].__setitem__("stackable", "yes"), 0, "stackable"),
        (lambda d: d["objects"][1].__setitem__("3d_coords", [0.1, float("nan"), 0.0]), 1, "3d_coords"),
        (lambda d: d["objects"][1].__setitem__("orientation", [float("inf"), 0, 0, 0]), 1, "orientation"),
        (lambda d: d["objects"][0].__setitem__("orientation", [2.0, 0.0, 0.0, 0.0]), 0, "orientation"),
        (lambda d: d["objects"][2].__setitem__("colour", 3), 2, "colour"),
        (lambda d: d["objects"][0].__setitem__("bbox", {"x": 1.0}), 0, "bbox"),
        (lambda d: d["objects"][0].__setitem__("mask", {"size": [1], "counts": "x"}), 0, "mask"),
        (lambda d: [o.__setitem__("id", 4) for o in d["objects"][:2]], 1, "id"),
        (lambda d: d["objects"][0].__setitem__("weight_gt", -3.0), 0, "weight_gt"),
    ],
)
def test_malformed_scene_names_object_and_field(mutate, obj, field):
    with pytest.raises(SceneValidationError) as err:
        scene_from_dict(_broken(mutate))
    assert err.value.obj == obj and err.value.field == field
    assert f"object {obj}" in str(err.value) and field in str(err.value)


def test_scene_level_errors():
    with pytest.raises(SceneValidationError, match="objects"):
        scene_from_dict({"split": "x"})
    with pytest.raises(SceneValidationError, match="relationships"):
        scene_from_dict(_broken(lambda d: d["relationships"].__setitem__("left", [[9]])))
    with pytest.raises(SceneValidationError):
        scene_from_dict([1, 2, 3])


def test_invalid_json_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"objects": [')
    with pytest.raises(SceneValidationError, match="not valid JSON"):
        load_scene(bad)


def test_atomic_save_leaves_nothing_on_failure(tmp_path):
    scene = scene_from_dict(make_scene_dict())
    scene.objects[0].extra["unserialisable"] = object()
    with pytest.raises(TypeError):
        save_scene(tmp_path / "out.json", scene)
    assert list(tmp_path.iterdir()) == []


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner, max_size=6),
    max_leaves=25,
)
object_keys = st.sampled_from(list(make_scene_dict()["objects"][0]) + ["id"])


@st.composite
def mutated_scenes(draw):
    """Valid scenes with random fields replaced, removed or added: close enough to reach deep validation."""
    d = copy.deepcopy(make_scene_dict(draw(st.integers(0, 3))))
    for _ in range(draw(st.integers(1, 4))):
        objects = d.get("objects")
        has_objects = isinstance(objects, list) and objects and all(isinstance(o, dict) for o in objects)
        target = draw(st.sampled_from(["scene", "object"])) if has_objects else "scene"
        if target == "object":
            obj = d["objects"][draw(st.integers(0, len(d["objects"]) - 1))]
            key = draw(object_keys)
        else:
            obj = d
            key = draw(st.sampled_from(list(d) + ["extra"]))
        if draw(st.booleans()):
            obj.pop(key, None)
        else:
            obj[key] = draw(json_values)
    return d


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scenes())
def test_loader_fuzz_raises_only_scene_validation_error(d):
    try:
        scene = scene_from_dict(d)
    except SceneValidationError:
        return
    # Whatever loads must save and load again to the same thing.
    again = scene_to_dict(scene_from_dict(scene_to_dict(scene)))
    assert again == scene_to_dict(scene)
    for o in scene.objects:
        assert all(math.isfinite(v) for v in o.position)


@settings(max_examples=200, deadline=None)
@given(json_values)
def test_loader_fuzz_arbitrary_json(value):
    try:
        scene_from_dict(value)
    except SceneValidationError:
        pass

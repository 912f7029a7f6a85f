"""Scene and instruction files that cannot be used raise ``SceneValidationError`` naming the file (and the field),
never a ``UnicodeDecodeError``, ``JSONDecodeError``, ``KeyError`` or ``OSError``."""
from __future__ import annotations

import json

import pytest

from muble.core.errors import SceneValidationError
from muble.core.interfaces import Instruction
from muble.io.instructions_io import instruction_to_dict, load_instruction, program_step
from muble.io.scene_io import load_scene, read_json, scene_from_dict, scene_to_dict

SCENE = {"objects": [{"file": "mug1", "name": "mug", "shape": "cylindrical", "size": "small",
                      "material": "ceramic", "colour": "red", "3d_coords": [0.1, 0.2, 0.8],
                      "orientation": [1.0, 0.0, 0.0, 0.0], "weight_gt": 250.0, "stackable": False,
                      "stack_base": False, "pickupable": True, "stiffness": 5000.0}]}
INSTRUCTION = instruction_to_dict(Instruction(instruction="Move the mug to the left.", template_id="move_single",
                                              task_id="move", program=[program_step("scene")]))


@pytest.mark.parametrize("content, says", [
    (json.dumps(SCENE)[:70].encode(), "truncated"),
    (b"", "truncated"),
    (bytes(range(128, 256)) * 4, "not UTF-8"),
    (b"\x89PNG\r\n\x1a\n" + bytes(200), "not UTF-8"),
    (json.dumps(SCENE).encode("utf-16"), "UTF-16"),
    (json.dumps(SCENE).encode("utf-16-le"), "UTF-16"),
    (json.dumps({**SCENE, "lamp_params": {"energy": float("nan")}}).encode(), "NaN"),
    (b'{"objects": [], "x": -Infinity}', "-Infinity"),
    (b'{"objects": [' + b"[" * 100_000, "JSON"),
])
def test_unreadable_file_names_the_file(tmp_path, content, says):
    path = tmp_path / "scene.json"
    path.write_bytes(content)
    with pytest.raises(SceneValidationError) as err:
        load_scene(path)
    assert str(path) in str(err.value) and says in str(err.value)


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(SceneValidationError, match="does not exist"):
        read_json(tmp_path / "none.json")
    with pytest.raises(SceneValidationError, match="cannot be read"):
        read_json(tmp_path)


def test_utf8_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "scene.json"
    path.write_bytes(json.dumps(SCENE).encode("utf-8-sig"))
    assert scene_to_dict(load_scene(path)) == scene_to_dict(scene_from_dict(SCENE))


def test_schema_error_names_file_object_and_field(tmp_path):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({"objects": [{**SCENE["objects"][0], "weight_gt": "heavy"}]}))
    with pytest.raises(SceneValidationError) as err:
        load_scene(path)
    assert (err.value.obj, err.value.field) == (0, "weight_gt")
    assert str(err.value).startswith(f"{path}: object 0, field 'weight_gt'")


@pytest.mark.parametrize("change, says", [
    (lambda d: d.pop("program"), "field 'program'"),
    (lambda d: d.update(program=[]), "program"),
    (lambda d: d.update(template_id=7), "field 'template_id'"),
    (lambda d: d.update(instruction=["move"]), "field 'instruction'"),
    (lambda d: d.update(ground_truth_actions=3), "field 'ground_truth_actions'"),
    (lambda d: d.update(image_index="0"), "field 'image_index'"),
])
def test_bad_instruction_names_the_file_and_field(tmp_path, change, says):
    record = json.loads(json.dumps(INSTRUCTION))
    change(record)
    path = tmp_path / "instruction.json"
    path.write_text(json.dumps(record))
    with pytest.raises(SceneValidationError) as err:
        load_instruction(path)
    assert str(path) in str(err.value) and says in str(err.value)


def test_instruction_file_without_an_instruction_is_not_an_error(tmp_path):
    path = tmp_path / "instruction.json"
    path.write_text(json.dumps({"split": "val", "instruction": None, "skipped": "no template applies"}))
    record, instruction = load_instruction(path)
    assert instruction is None and record["skipped"]
    path.write_text(json.dumps([INSTRUCTION]))
    with pytest.raises(SceneValidationError, match="expected a JSON object, got list"):
        load_instruction(path)
    path.write_text(json.dumps(INSTRUCTION))
    assert load_instruction(path)[1].template_id == "move_single"

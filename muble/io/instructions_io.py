"""SHOP-VRB2 instruction files: ``{info, instructions[]}`` with CLEVR-IEP programs, read and written losslessly.

Each instruction carries ``instruction`` (text), ``program`` (steps ``{type, input, input_value, output}``),
``template_id``, ``task_id``, ``image_filename``, ``image_index`` and ``split``; other keys of the original
release (``template_internal_idx``, ``template_overall_idx``, ``instruction_idx`` …) and MuBlE's own additions
are kept in ``Instruction.extra``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from muble.core.errors import SceneValidationError
from muble.core.interfaces import Instruction
from muble.io.scene_io import in_file, read_json, write_json_atomic

# The ten SHOP-VRB2 task templates, in their overall order (``template_overall_idx`` 0..9): the benchmark's default
# template mix (``dataset.templates``). The tasks plugin's templates data defines each one under this id and index.
SHOPVRB2_TEMPLATES = ("measure_weight_single", "measure_weight_multi", "pick_up_lightest", "move_single", "remove",
                      "move_weight", "stack_simple", "stack_weight", "stack_three", "stack_order")
_REQUIRED = ("instruction", "program", "template_id", "task_id")
_KNOWN = {*_REQUIRED, "image_filename", "image_index", "split"}
_STEP_KEYS = ("type", "input", "input_value", "output")


def _where(index: int | None) -> str:
    return f"instruction {index}: " if index is not None else ""


def program_from_list(program: Any, index: int | None = None) -> list[dict[str, Any]]:
    """Validate a CLEVR-IEP program: a list of dicts, each with a string ``type``."""
    if not isinstance(program, list) or not program:
        raise SceneValidationError(f"{_where(index)}'program' must be a non-empty list of steps", field="program")
    for k, step in enumerate(program):
        if not isinstance(step, dict) or not isinstance(step.get("type"), str):
            raise SceneValidationError(f"{_where(index)}program step {k} must be a dict with a string 'type', "
                                       f"got {step!r:.60}", field="program")
    return [dict(step) for step in program]


def instruction_from_dict(d: Any, index: int | None = None) -> Instruction:
    """One instruction of an instruction file, validated (``index`` is named in a ``SceneValidationError``): the
    known keys become fields, every other key goes to ``Instruction.extra``."""
    if not isinstance(d, dict):
        raise SceneValidationError(f"{_where(index)}expected a JSON object, got {type(d).__name__}")
    for key in _REQUIRED:
        if key not in d:
            raise SceneValidationError(f"{_where(index)}missing required field", field=key)
    for key in ("instruction", "template_id", "task_id"):
        if not isinstance(d[key], str):
            raise SceneValidationError(f"{_where(index)}expected a string", field=key)
    image_index = d.get("image_index", 0)
    if not isinstance(image_index, int) or isinstance(image_index, bool):
        raise SceneValidationError(f"{_where(index)}expected an integer", field="image_index")
    return Instruction(
        instruction=d["instruction"],
        program=program_from_list(d["program"], index),
        template_id=d["template_id"],
        task_id=d["task_id"],
        image_filename=str(d.get("image_filename", "")),
        image_index=image_index,
        split=str(d.get("split", "")),
        extra={k: v for k, v in d.items() if k not in _KNOWN},
    )


def program_step(type_: str, input_: Any = None, input_value: Any = None, output: Any = None) -> dict[str, Any]:
    """One program step in the original key order."""
    return {"type": type_, "input": input_, "input_value": input_value, "output": output}


def instruction_to_dict(ins: Instruction) -> dict[str, Any]:
    """The original key order: split, image_filename, image_index, instruction, program, template_id, task_id."""
    d: dict[str, Any] = {"split": ins.split, "image_filename": ins.image_filename, "image_index": ins.image_index,
                         "instruction": ins.instruction,
                         "program": [{k: step[k] for k in _STEP_KEYS if k in step}
                                     | {k: v for k, v in step.items() if k not in _STEP_KEYS}
                                     for step in ins.program],
                         "template_id": ins.template_id, "task_id": ins.task_id}
    d.update(ins.extra)
    return d


def load_instruction(path: str | Path, index: int | None = None) -> tuple[dict[str, Any], Instruction | None]:
    """One per-index instruction file as ``muble generate`` writes it: the record as stored, and its instruction, or
    None where the record says no template applied to the scene (``"instruction": null``).

    A file that cannot be read or breaks the schema raises ``SceneValidationError`` naming the file and the field.
    """
    record = read_json(path)
    try:
        if not isinstance(record, dict):
            raise SceneValidationError(f"expected a JSON object, got {type(record).__name__}")
        actions = record.get("ground_truth_actions", [])
        if not isinstance(actions, list):
            raise SceneValidationError(f"expected a list of [name, params], got {type(actions).__name__}",
                                       field="ground_truth_actions")
        if "instruction" in record and record["instruction"] is None:
            return record, None
        return record, instruction_from_dict(record, index)
    except SceneValidationError as e:
        raise in_file(e, path) from e


def load_instructions(path: str | Path) -> tuple[dict[str, Any], list[Instruction]]:
    """Load an ``{info, instructions}`` file; returns the info block and the instructions."""
    data = read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("instructions"), list):
        raise SceneValidationError(f"{path}: an instruction file needs an 'instructions' list",
                                   field="instructions")
    info = data.get("info", {})
    if not isinstance(info, dict):
        raise SceneValidationError(f"{path}: expected a dict", field="info")
    return info, [instruction_from_dict(d, i) for i, d in enumerate(data["instructions"])]


def save_instructions(path: str | Path, instructions: list[Instruction], info: dict[str, Any] | None = None) -> None:
    """Write an instruction file atomically, in the original schema."""
    write_json_atomic(path, {"info": info or {}, "instructions": [instruction_to_dict(i) for i in instructions]})

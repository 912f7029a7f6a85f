"""What an agent may know: the scene graph as a robot perceives it, plus what it measured itself.

Every world (symbolic or physical) builds the scene an agent observes with ``agent_view``; ground truth stays
with the world, the success checks and the ``observations_gt`` of sequence files.

Instructions too (``agent_instruction``): an agent gets the text and the program without the recorded outputs
and inputs (target ids, true weights: both are computed on the ground truth) and none of the instruction file's
ground-truth records.

The view is an allow-list, so a property nobody thought of stays hidden by default:
- visible: identity and visible attributes (model, category, shape, size, material, colour), pose, bbox,
  mask, affordances (stackable, stack base, pickupable), the gripper flags and the contact state (what an
  object stands on or touches, which a camera sees);
- hidden until measured in this episode: ``weight`` (grams, from ``weigh``) and the properties other primitives
  measure, each reported as ``extra["<property>_measured"]`` (``MEASURED_EXTRA``): stiffness (N/m, ``squeeze``),
  friction (coefficient, ``push``), the centre of mass's offset ([x, y] mm, ``balance``) and whether it rattles
  (``shake``);
- never shown: ``weight_gt``, the ground-truth ``stiffness``, a scene file's pre-filled ``weight``, and every
  other key a scene file or an object set carries (friction, geometry parameters, …). An object set may hide
  visible fields as well (``ObjectSet.hidden_properties``).
"""
from __future__ import annotations

import copy
from typing import Iterable, Mapping

import numpy as np

from muble.core.interfaces import Instruction
from muble.core.physical_properties import Derived
from muble.core.scene import SceneGraph, SceneObject

# Keys of ``SceneObject.extra`` an agent may see: the gripper's flags and the physical contact state.
VISIBLE_EXTRA = ("in_hand", "raised", "approached", "gripper_over", "touching", "tilt_deg", "speed")
TOUCHING_TABLE = "table"  # what ``extra["touching"]`` names the table (beside object ids)
# Fields of ``SceneObject`` that carry ground truth and never reach an agent.
GROUND_TRUTH_FIELDS = ("weight_gt", "stiffness")
# Measured properties besides the weight (``SceneObject.weight``): the name a primitive reports it under
# (``PrimitiveAction.measures``) -> the ``extra`` key an agent's view carries it under once measured.
# Read from the registered properties (``muble.core.physical_properties``): every one measured into ``extra``.
MEASURED_EXTRA: Mapping[str, str] = Derived(lambda props: {name: p.measured_key for name, p in props.items()
                                                           if p.measured_key is not None})
MEASURED_STIFFNESS = "stiffness_measured"
# Scene-level fields an agent may see (everything else of the scene file, ``extra`` included, stays hidden).
_SCENE_VISIBLE = ("split", "image_index", "image_filename", "directions", "camera_params", "lamp_params", "table",
                  "robot", "relationships")


def plain_measurement(value) -> bool | float | list[float]:
    """A primitive's measurement as plain Python: a yes/no, a number, or a list of numbers ([x, y] mm)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return [float(v) for v in value]
    return bool(value) if isinstance(value, (bool, np.bool_)) else float(value)


def agent_object(obj: SceneObject, measured: Mapping[str, float] | None = None,
                 hidden: Iterable[str] = ()) -> SceneObject:
    """``obj`` as an agent may know it; ``measured`` holds what this agent measured of it ({"weight": g, …})."""
    measured = measured or {}
    extra = {k: copy.deepcopy(obj.extra[k]) for k in VISIBLE_EXTRA if k in obj.extra}
    for name, key in MEASURED_EXTRA.items():
        if name in measured:
            extra[key] = plain_measurement(measured[name])
    view = SceneObject(
        id=obj.id, model=obj.model, name=obj.name, shape=obj.shape, size=obj.size, material=obj.material,
        colour=obj.colour, position=obj.position.copy(), orientation=obj.orientation.copy(), weight_gt=None,
        stackable=obj.stackable, stack_base=obj.stack_base, pickupable=obj.pickupable,
        weight=float(measured["weight"]) if "weight" in measured else None, rotation=obj.rotation,
        pixel_coords=copy.deepcopy(obj.pixel_coords), movability=obj.movability, bbox=copy.deepcopy(obj.bbox),
        scale_factor=obj.scale_factor, mask=obj.mask, stiffness=None, extra=extra, explicit_id=obj.explicit_id)
    for name in hidden:
        if name in GROUND_TRUTH_FIELDS or name == "weight":
            continue  # hidden already (or shown only as measured)
        if hasattr(view, name) and name not in ("id", "position", "orientation"):
            setattr(view, name, None)
        view.extra.pop(name, None)
    return view


def agent_view(scene: SceneGraph, measured: Mapping[int, Mapping[str, float]] | None = None,
               hidden: Iterable[str] = ()) -> SceneGraph:
    """A copy of ``scene`` that carries only what an agent may know (see the module doc).

    ``measured`` maps object id to the values this agent measured in this episode ({"weight": g,
    "stiffness": N/m, "friction": …}); ``hidden`` names further properties to withhold (an object set's hidden
    properties).
    """
    measured = measured or {}
    hidden = tuple(hidden)
    view = SceneGraph(objects=[agent_object(o, measured.get(o.id), hidden) for o in scene.objects])
    for name in _SCENE_VISIBLE:
        setattr(view, name, copy.deepcopy(getattr(scene, name)))
    return view


# Keys of a program step an agent may see. The recorded ``output`` of a step is ground truth (the target ids
# chosen on the initial scene, the true weights of a ``query_weight``), and so is the recorded ``input``: it holds
# the previous step's output (after a ``filter_weight`` it names the lightest object), so both are left out. The
# chain structure needs neither (``muble.programs.program``: each step takes the output of the one before).
PROGRAM_STEP_KEYS = ("type", "input_value", "side_inputs", "value_inputs")


def agent_program(program: list) -> list:
    """``program`` as an agent may know it: each step's type and its words (``input_value``), nothing computed
    on the ground truth (``input`` is kept as null, so consumers of the original schema still find it)."""
    return [{"input": None, **{k: copy.deepcopy(step[k]) for k in PROGRAM_STEP_KEYS if k in step}}
            if isinstance(step, dict) else step for step in program]


def agent_instruction(instruction: Instruction) -> Instruction:
    """``instruction`` as an agent may know it: the text and the program without recorded outputs or inputs
    (``agent_program``); none of the instruction file's other records (ground-truth actions, the task's target …)."""
    return Instruction(instruction.instruction, agent_program(instruction.program), instruction.template_id,
                       instruction.task_id, instruction.image_filename, instruction.image_index, instruction.split)


def leaks(scene: SceneGraph, measured: Mapping[int, Mapping[str, float]] | None = None) -> list[str]:
    """What in ``scene`` an agent should not know: ground truth, or a measured value it did not measure.

    Empty for a scene built by ``agent_view``; the benchmark's tests (and third-party worlds) check with it.
    """
    measured = measured or {}
    found = []
    for o in scene.objects:
        mine = measured.get(o.id, {})
        if o.weight_gt is not None:
            found.append(f"object {o.id}: weight_gt")
        if o.stiffness is not None:
            found.append(f"object {o.id}: stiffness")
        if o.weight is not None and o.weight != mine.get("weight"):
            found.append(f"object {o.id}: weight {o.weight} not measured by the agent")
        for name, key in MEASURED_EXTRA.items():
            if key in o.extra and o.extra[key] != mine.get(name):
                found.append(f"object {o.id}: {name} not measured by the agent")
        for key in o.extra:
            if key not in VISIBLE_EXTRA and key not in MEASURED_EXTRA.values():
                found.append(f"object {o.id}: extra['{key}']")
    if scene.extra:
        found.append(f"scene extra keys {sorted(scene.extra)}")
    return found

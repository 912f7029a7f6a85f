"""Tracks and observation modes: what an agent is told about the task and about the scene.

The benchmark runs the same episodes under each (``docs/protocol.md``), so perception and reasoning errors can be
told apart:

- **tracks** (``track_instruction``): ``program`` gives the instruction's text and its program with nothing
  computed on the ground truth (``muble.core.observation.agent_instruction``); ``language`` the text only.
- **observation modes** (``ObservationView``):
  - ``graph``: the agent view of ``muble.core.observation`` (ids, poses, visible attributes, contact state);
  - ``masks``: the images (RGB, depth and the instance segmentation, whose pixels hold object ids), and per
    object its id, instance mask (COCO RLE of the latest image), pose, bounding box and contact state; no
    attribute words (model, name, shape, size, material, colour) and no affordance flags;
  - ``image``: RGB and depth only. No object ids anywhere: the scene lists no objects, object-keyed sensor
    readings are dropped, and a primitive's object argument is a pixel ``[x, y]`` (column, row) of the latest
    image of the first camera, or ``{"pixel": [x, y], "camera": NAME}``, which ``resolve_pixels`` turns into
    the object seen there.
  In every mode the measurements the agent made (its ``last_result``, the proprioception) reach it.

A privileged agent (``Agent.privileged``, the oracle) plans from the graph view and the program, and acts
through the mode's action form: in ``image`` mode ``express_with_pixels`` names each object it targets by a
visible pixel of it, so the oracle's success proves each mode solvable.
"""
from __future__ import annotations

import copy
import dataclasses
import re
from typing import Any, Iterable

import numpy as np

from muble.core.interfaces import Instruction
from muble.core.observation import agent_instruction
from muble.core.params import specs
from muble.core.scene import SceneGraph, SceneObject
from muble.core.types import ActionCall, ActionResult, Frame, Observation, ObservationMode, Track

TRACKS = tuple(t.value for t in Track)
MODES = tuple(m.value for m in ObservationMode)
# Fields of a scene object that ``masks`` mode keeps (with ``extra``: gripper flags, contact state, what the agent
# measured); everything else of the graph view (attribute words, affordances, scale) is withheld.
MASKS_OBJECT_FIELDS = ("id", "position", "orientation", "bbox", "mask", "pixel_coords", "weight", "extra",
                       "explicit_id")
# Scene-level fields ``image`` mode keeps (none of them names an object).
IMAGE_SCENE_FIELDS = ("split", "image_index", "image_filename", "directions", "camera_params", "lamp_params")
# Parameter kinds that name an object (``muble.core.params``): given as pixels in ``image`` mode.
OBJECT_KINDS = ("object", "place")
_IDS_IN_TEXT = re.compile(r"\b(objects?|ids?|targets?|held)(\s*[=:]?\s*)(\[[\d,\s]*\]|\d+)", re.IGNORECASE)


def check_track(track: str) -> Track:
    """``track`` as a ``Track`` (a member or its name); otherwise ``ValueError`` naming the valid ones."""
    if track not in TRACKS:
        raise ValueError(f"unknown track '{track}'; valid tracks: {', '.join(TRACKS)}")
    return Track(track)


def check_mode(mode: str) -> ObservationMode:
    """``mode`` as an ``ObservationMode`` (a member or its name); otherwise ``ValueError`` naming the valid ones."""
    if mode not in MODES:
        raise ValueError(f"unknown observation mode '{mode}'; valid modes: {', '.join(MODES)}")
    return ObservationMode(mode)


def track_instruction(instruction: Instruction, track: str) -> Instruction:
    """The instruction as an agent on ``track`` is told it: ``program`` (text and program, nothing computed on the
    ground truth) or ``language`` (the text only: the program is empty)."""
    told = agent_instruction(instruction)
    if check_track(track) == "language":
        told = dataclasses.replace(told, program=[])
    return told


def _masks_object(obj: SceneObject, rle: Any) -> SceneObject:
    kept = {name: copy.deepcopy(getattr(obj, name)) for name in MASKS_OBJECT_FIELDS}
    kept["mask"] = rle
    # The withheld attribute words and affordances are None, which SceneObject's str and bool fields do not declare:
    # the masks view is a SceneObject whose agent reads only MASKS_OBJECT_FIELDS (muble.core.scene has no type for
    # a view with fields withheld).
    return SceneObject(model=None, name=None, shape=None, size=None,  # type: ignore[arg-type]
                       material=None, colour=None, weight_gt=None,  # type: ignore[arg-type]
                       stackable=None, stack_base=None, pickupable=None, **kept)  # type: ignore[arg-type]


def _without_ids(value: Any) -> Any:
    """A sensor reading with every object-keyed entry removed (mappings keyed by object id) and ``held_object``
    turned into whether anything is held."""
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
                continue
            if key == "held_object":
                out["holding"] = item is not None
                continue
            out[key] = _without_ids(item)
        return out
    return copy.deepcopy(value)


def _scrub_text(text: str | None) -> str | None:
    return None if text is None else _IDS_IN_TEXT.sub(lambda m: m.group(1) + m.group(2) + "…", text)


def _frames(images: dict[str, Frame], segmentation: bool) -> dict[str, Frame]:
    return {name: Frame(camera=f.camera, rgb=f.rgb, depth=f.depth,
                        segmentation=f.segmentation if segmentation else None, normals=f.normals)
            for name, f in images.items()}


class ObservationView:
    """Turns the world's observation (the graph view with the rendered frames) into a mode's observation."""

    def __init__(self, mode: str = "graph"):
        self.mode = check_mode(mode)

    @property
    def needs_images(self) -> bool:
        return self.mode != "graph"

    def __call__(self, observation: Observation) -> Observation:
        if self.mode == "graph":
            return observation
        if not observation.images:
            raise ValueError(f"observation mode '{self.mode}' shows the agent images, but nothing was rendered; "
                             "configure a renderer (renderer=mujoco or renderer=blender) with rendering on")
        if self.mode == "masks":
            return self._masks(observation)
        return self._image(observation)

    def _masks(self, observation: Observation) -> Observation:
        scene = observation.scene
        frame = next(iter(observation.images.values()))
        rles: list[Any] = [None] * len(scene.objects)
        if frame.segmentation is not None:
            from muble.generation.ground_truth import encode_masks

            rles = encode_masks(frame.segmentation, scene.ids)
        view = SceneGraph(objects=[_masks_object(o, r) for o, r in zip(scene.objects, rles)])
        for name in IMAGE_SCENE_FIELDS + ("relationships", "table", "robot"):
            setattr(view, name, copy.deepcopy(getattr(scene, name)))
        return dataclasses.replace(observation, scene=view, images=_frames(observation.images, True))

    def _image(self, observation: Observation) -> Observation:
        view = SceneGraph(objects=[])
        for name in IMAGE_SCENE_FIELDS:
            setattr(view, name, copy.deepcopy(getattr(observation.scene, name)))
        result = observation.last_result
        if result is not None:
            result = ActionResult(result.success, copy.deepcopy(result.measurement),
                                  _scrub_text(result.failure_reason), {})
        return dataclasses.replace(observation, scene=view, images=_frames(observation.images, False),
                                   measurements=_without_ids(observation.measurements), last_result=result)


def _object_params(declared: Iterable[Any]) -> set[str]:
    return {p.name for p in specs(declared) if p.kind in OBJECT_KINDS}


def _pixel_of(value: Any, cameras: list[str]) -> tuple[str | None, int, int] | None:
    """(camera, x, y) of a pixel argument, or None if ``value`` is not one; the camera is None when the
    observation has no images and the argument names none."""
    camera = cameras[0] if cameras else None
    if isinstance(value, dict) and set(value) <= {"pixel", "camera"} and "pixel" in value:
        camera, value = value.get("camera", camera), value["pixel"]
    if isinstance(value, (list, tuple)) and len(value) == 2 and all(
            isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value):
        return camera, int(value[0]), int(value[1])
    return None


def resolve_pixels(action: ActionCall, observation: Observation, declared: Iterable[Any]) -> ActionCall | str:
    """``action`` with each pixel in an object argument replaced by the id of the object seen there in
    ``observation``'s frames; a string saying what is wrong when a pixel names no object (or an object argument is
    given as an id, which ``image`` mode does not show)."""
    if not isinstance(action, ActionCall) or not isinstance(action.params, dict):
        return action
    names = _object_params(declared)
    params = dict(action.params)
    cameras = list(observation.images)
    for key in names & set(params):
        value = params[key]
        if isinstance(value, str):
            continue  # a table part: no object named
        pixel = _pixel_of(value, cameras)
        if pixel is None:
            return (f"{action.name}: in observation mode 'image', '{key}' names an object by a pixel [x, y] of the "
                    f"latest image (or {{'pixel': [x, y], 'camera': name}}), got {value!r:.60}")
        camera, x, y = pixel
        frame = None if camera is None else observation.images.get(camera)
        if frame is None:
            return f"{action.name}: '{key}' names camera {camera!r:.40}; cameras: {', '.join(cameras)}"
        if frame.segmentation is None:
            return f"{action.name}: pixel targets need segmentation from the renderer (renderer.segmentation=true)"
        height, width = frame.segmentation.shape
        if not (0 <= x < width and 0 <= y < height):
            return f"{action.name}: pixel [{x}, {y}] of '{key}' is outside the {width}x{height} image"
        label = int(frame.segmentation[y, x])
        if label not in observation.scene.ids:
            return f"{action.name}: pixel [{x}, {y}] of '{key}' shows no object (table, robot or background)"
        params[key] = label
    return ActionCall(action.name, params)


def visible_pixel(frame: Frame, obj_id: int) -> list[int] | None:
    """A pixel [x, y] of ``frame`` that shows ``obj_id``: the one of its mask nearest the mask's median, so it
    lies well inside the silhouette; None when the object is not in view."""
    if frame.segmentation is None:
        return None
    rows, cols = np.nonzero(frame.segmentation == obj_id)
    if rows.size == 0:
        return None
    r, c = np.median(rows), np.median(cols)
    k = int(np.argmin((rows - r) ** 2 + (cols - c) ** 2))
    return [int(cols[k]), int(rows[k])]


def express_with_pixels(action: ActionCall, observation: Observation, declared: Iterable[Any]) -> ActionCall:
    """A privileged agent's ``action`` in ``image`` mode's form: every object id argument given as a visible
    pixel of that object in the first camera's latest image (left as the id, and so refused, when the object
    is out of view)."""
    if not isinstance(action, ActionCall) or not isinstance(action.params, dict) or not observation.images:
        return action
    frame = next(iter(observation.images.values()))
    params = dict(action.params)
    for key in _object_params(declared) & set(params):
        value = params[key]
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            pixel = visible_pixel(frame, int(value))
            if pixel is not None:
                params[key] = pixel
    return ActionCall(action.name, params)

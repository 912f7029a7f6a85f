"""Per-step sequence files in the original MuBlE schema (observations after every primitive)."""
from __future__ import annotations

from typing import Any

import numpy as np

from muble.core.interfaces import Instruction
from muble.core.scene import SceneGraph
from muble.core.types import SEG_ROBOT, SEG_TABLE, ActionCall, Observation
from muble.episode.loop import EpisodeResult
from muble.generation.ground_truth import encode_mask
from muble.io.action_names import check_style, named
from muble.io.scene_io import object_to_dict

_FLAGS = ("in_hand", "raised", "approached", "gripper_over")


def encode_rle(mask: np.ndarray) -> dict[str, Any]:
    """COCO RLE of a boolean mask as plain data ({size, counts})."""
    return encode_mask(mask).to_dict()


def _finite(values: Any) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).reshape(-1)]


def _objects(scene: SceneGraph, observation: Observation, camera: str) -> list[dict[str, Any]]:
    frame = observation.images.get(camera)
    out = []
    for o in scene.objects:
        d = object_to_dict(o)
        for flag in _FLAGS:
            d.pop(flag, None)
        d["pos"] = _finite(o.position)
        d["ori"] = _finite(o.orientation)
        for flag in _FLAGS:
            d[flag] = bool(o.extra.get(flag, False))
        if frame is not None and frame.segmentation is not None:
            d["mask"] = encode_rle(frame.segmentation == o.id)
        out.append(d)
    return out


def _robot(observation: Observation, action: ActionCall | None, weight: float | None,
           action_names: str = "registry") -> dict[str, Any]:
    m = observation.measurements
    target = None if action is None else action.params.get("target")
    gripper = float(m.get("gripper_command", -1.0))
    return {
        "pos": _finite(m["ee_pos"]) if "ee_pos" in m else None,
        "ori": _finite(m["ee_quat"]) if "ee_quat" in m else None,
        "gripper_action": gripper,
        "gripper_closed": gripper > 0,
        "weight_measurement": 0.0 if weight is None else float(weight),
        "action": ["START", None] if action is None else [named(action.name, action_names), target],
    }


def sequence_dict(instruction: Instruction, episode: EpisodeResult, image_paths: list[str],
                  camera: str = "front", action_names: str = "registry", registry: Any = None) -> dict[str, Any]:
    """The sequence file: ``observations`` as the agent saw them, ``observations_gt`` with ground truth too.

    ``action_names="original"`` writes the original release's primitive names (``muble.io.action_names``).
    ``registry`` (default: the plugin registry) tells which primitives measure a weight.
    """
    if registry is None:
        from muble.plugins.registry import get_registry

        registry = get_registry()
    check_style(action_names)
    if episode.initial is None:
        raise ValueError("the episode has no initial observation (it ended before the agent saw the scene): there "
                         "is no sequence to write")
    observations, observations_gt = [], []
    weight = None
    steps: list[tuple[ActionCall | None, Observation, SceneGraph | None]] = [
        (None, episode.initial, episode.initial_gt)] + [(s.action, s.observation, s.scene_gt) for s in episode.steps]
    for i, (action, observation, scene_gt) in enumerate(steps):
        if action is not None:  # step i's action, whose result is that of episode.steps[i - 1]
            measured = episode.steps[i - 1].result.measurement
            if measured is not None and registry.measures(action.name) == "weight":
                weight = measured
        robot = _robot(observation, action, weight, action_names)
        # What the agent saw (its measurements only) and, apart, the ground truth at the same moment.
        observations.append({"robot": robot, "objects": _objects(observation.scene, observation, camera)})
        gt = dict(robot)
        truth = scene_gt if scene_gt is not None else observation.scene
        gt["grasped_obj_idx"] = next((o.id for o in truth.objects if o.extra.get("in_hand")), None)
        frame = observation.images.get(camera)
        if frame is not None and frame.segmentation is not None:
            gt["robot_mask"] = encode_rle(frame.segmentation == SEG_ROBOT)
            gt["table_mask"] = encode_rle(frame.segmentation == SEG_TABLE)
        observations_gt.append({"robot": gt, "objects": _objects(truth, observation, camera)})
    spec = instruction.extra.get("task") or {}
    return {
        "info": {
            "image_filename": instruction.image_filename,
            "instruction": instruction.instruction,
            "task": {"task": spec.get("task", instruction.task_id), "target": spec.get("target")},
        },
        "observations": observations,
        "observations_gt": observations_gt,
        "image_paths": image_paths,
        "result": episode.outcome.value,
    }

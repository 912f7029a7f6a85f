"""Observations, actions and results as plain JSON data: what Gymnasium observations and remote messages carry.

The scene is the agent's view (``muble.core.observation.agent_view``) in the SHOP-VRB2 scene schema, so it holds
no ground truth: ``weight_gt`` is absent, ``weight`` is what the agent measured (or null), and the gripper and
contact flags (``in_hand``, ``raised``, ``approached``, ``gripper_over``, ``touching`` …) are object keys.
``observation_from_plain`` turns the data back into an ``Observation``, so an in-process ``Agent`` (the oracle)
can act on what a Gymnasium environment or the server sends.
"""
from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np

from muble.core.errors import SceneValidationError
from muble.core.scene import SceneGraph
from muble.core.types import ActionCall, ActionResult, Answer, Observation
from muble.io.scene_io import scene_from_dict, scene_to_dict


def plain(value: Any) -> Any:
    """JSON-ready data: numpy scalars and arrays become numbers and lists, non-finite floats None, the rest str."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return str(value)


def result_to_plain(result: ActionResult | None) -> dict[str, Any] | None:
    if result is None:
        return None
    return {"success": bool(result.success), "measurement": plain(result.measurement),
            "failure_reason": result.failure_reason, "info": plain(result.info)}


def result_from_plain(d: dict[str, Any] | None) -> ActionResult | None:
    if d is None:
        return None
    return ActionResult(bool(d["success"]), d.get("measurement"), d.get("failure_reason"), dict(d.get("info") or {}))


def scene_to_plain(scene: SceneGraph) -> dict[str, Any]:
    """An agent's view of a scene as plain data (``weight_gt`` is never written: the view has none)."""
    return plain(scene_to_dict(scene))


# Object fields the scene schema requires that an observation mode may withhold (``masks`` mode sends no
# attribute words): key in the file -> SceneObject attribute, and the stand-in parsed in their place.
_WITHHELD = {"file": ("model", "?"), "name": ("name", "?"), "shape": ("shape", "?"), "size": ("size", "?"),
             "material": ("material", "?"), "colour": ("colour", "?"), "stackable": ("stackable", False),
             "stack_base": ("stack_base", False), "pickupable": ("pickupable", False)}


def scene_from_plain(d: Any) -> SceneGraph:
    """The agent's view back from ``scene_to_plain``'s data, in any observation mode.

    Objects carry no ``weight_gt`` (None afterwards). Attribute words and flags the mode withholds (null or
    absent in ``masks`` mode) stay None, as the agent was given them; ``image`` mode's scene has no objects.
    """
    if not isinstance(d, dict) or not isinstance(d.get("objects"), list):
        raise SceneValidationError("an observed scene must be a JSON object with a list of 'objects'")
    filled = copy.copy(d)
    withheld: list[list[str]] = []
    objects = []
    for o in d["objects"]:
        if isinstance(o, dict):
            # The file schema requires weight_gt and the attribute words; an agent's view has no weight_gt and,
            # in masks mode, no words: parse with stand-ins and clear them again.
            missing = [key for key in _WITHHELD if o.get(key) is None]
            o = {**o, "weight_gt": 1.0, **{key: _WITHHELD[key][1] for key in missing}}
        else:
            missing = []
        withheld.append(missing)
        objects.append(o)
    filled["objects"] = objects
    scene = scene_from_dict(filled)
    for o, missing in zip(scene.objects, withheld):
        o.weight_gt = None
        for key in missing:
            setattr(o, _WITHHELD[key][0], None)
    return scene


def observation_to_plain(observation: Observation) -> dict[str, Any]:
    """Everything of an observation but its images (those travel apart, as arrays or binary frames)."""
    return {"step": int(observation.step), "scene": scene_to_plain(observation.scene),
            "measurements": plain(observation.measurements), "last_result": result_to_plain(observation.last_result)}


def observation_from_plain(d: dict[str, Any], images: dict[str, Any] | None = None) -> Observation:
    return Observation(scene=scene_from_plain(d["scene"]), images=dict(images or {}),
                       measurements=dict(d.get("measurements") or {}),
                       last_result=result_from_plain(d.get("last_result")), step=int(d.get("step", 0)))


def decision_to_plain(decision: ActionCall | Answer | None) -> dict[str, Any]:
    """``{"name": ..., "params": {...}}`` for a call, ``{"answer": value}`` for an answer, ``{"stop": true}``."""
    if decision is None:
        return {"stop": True}
    if isinstance(decision, Answer):
        return {"answer": plain(decision.value)}
    return {"name": decision.name, "params": plain(decision.params)}


class MalformedDecision(ValueError):
    """A decision that is not of the documented shape."""


def decision_from_plain(d: Any) -> tuple[ActionCall | Answer | None, bool]:
    """(decision, stop) from ``decision_to_plain``'s shape; ``{"answer": v, "stop": false}`` answers and goes on.

    Raises ``MalformedDecision`` saying what the shape should be. Whether a well-formed call is valid (a known
    primitive, parameters of the declared kinds, targets in the scene) is the action loop's to judge.
    """
    if not isinstance(d, dict):
        raise MalformedDecision(f"a decision must be a JSON object, got {type(d).__name__}")
    stop = d.get("stop", True)
    if not isinstance(stop, bool):
        raise MalformedDecision(f"'stop' must be true or false, got {type(stop).__name__}")
    if "answer" in d:
        extra = sorted(set(d) - {"answer", "stop"})
        if extra:
            raise MalformedDecision(f"an answer takes only 'answer' and 'stop', got also {extra}")
        return Answer(d["answer"]), stop
    if "name" in d:
        extra = sorted(set(d) - {"name", "params"})
        if extra:
            raise MalformedDecision(f"a primitive call takes only 'name' and 'params', got also {extra}")
        params = d.get("params", {})
        if not isinstance(d["name"], str) or not isinstance(params, dict):
            raise MalformedDecision("a primitive call is {\"name\": str, \"params\": {name: value}}")
        return ActionCall(d["name"], dict(params)), True
    if d.get("stop") is True and set(d) == {"stop"}:
        return None, True
    raise MalformedDecision('a decision is {"name": ..., "params": {...}}, {"answer": ...} or {"stop": true}; '
                            f"got keys {sorted(map(str, d))[:8]}")

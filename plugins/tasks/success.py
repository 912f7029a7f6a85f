"""Success checks on the final scene graph (and answer), per task type, and the failure taxonomy.

Targets come from the program outputs recorded at generation time (the initial scene), because filters such as
``filter_table_part`` would select different objects once the robot has moved them.
"""
from __future__ import annotations

import logging
from typing import Any

from muble import Answer, ConfigError, Instruction, Outcome, PlanningError, SceneGraph
from muble.core.program import execute

from muble_plugins.tasks.geometry import broken, on_table_part, rests_on
from muble_plugins.tasks.planner import stack_pairs

log = logging.getLogger(__name__)

WEIGHT_TOLERANCE_G = 2.0  # absolute slack on an answered weight …
WEIGHT_TOLERANCE_REL = 0.02  # … or this fraction of it, whichever is larger


def recorded_final(instruction: Instruction, scene: SceneGraph) -> Any:
    """The final step's target: its recorded output, or the program run on ``scene`` with true weights."""
    final = instruction.program[-1].get("output")
    if final is not None:
        return final
    return execute(instruction.program, scene, weights="ground_truth").final


def weights_match(answer: Any, expected: list[float]) -> bool:
    values = answer.value if isinstance(answer, Answer) else answer
    if isinstance(values, dict):
        values = list(values.values())
    if not isinstance(values, (list, tuple)) or len(values) != len(expected):
        return False
    try:
        got = sorted(float(v) for v in values)
    except (TypeError, ValueError):
        return False
    return all(abs(g - e) <= max(WEIGHT_TOLERANCE_G, WEIGHT_TOLERANCE_REL * e) for g, e in zip(got, sorted(expected)))


def check(instruction: Instruction, scene: SceneGraph, answer: Answer | None) -> Outcome:
    """Judge one finished episode: success, or the failure class the final state shows."""
    if broken(scene):
        log.info("broken scene: objects %s left the table", broken(scene))
        return Outcome.BROKEN_SCENE
    try:
        target = recorded_final(instruction, scene)
    except (PlanningError, ConfigError) as e:
        log.info("program failure: %s", e)
        return Outcome.PROGRAM_FAILURE
    kind = instruction.program[-1]["type"]
    try:
        if kind == "query_weight":
            return Outcome.SUCCESS if answer is not None and weights_match(answer, target) else Outcome.INCORRECT_ANSWER
        if kind == "pick_up":
            obj = scene.object(target[0])
            ok = bool(obj.extra.get("in_hand")) and bool(obj.extra.get("raised"))
        elif kind == "move_to":
            part = instruction.program[-1]["input_value"]
            ok = all(on_table_part(scene.object(i), part, scene) for i in target)
        elif kind == "stack":
            ok = all(rests_on(scene.object(t), scene.object(b)) for t, b in stack_pairs(target))
        else:
            return Outcome.PROGRAM_FAILURE
    except KeyError as e:
        log.info("program failure: %s", e)
        return Outcome.PROGRAM_FAILURE
    return Outcome.SUCCESS if ok else Outcome.SCENE_INCONSISTENCY

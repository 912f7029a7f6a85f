"""Success checks on the final scene graph (and answer), per task type, and the failure taxonomy.

Targets come from the program outputs recorded at generation time (the initial scene), because filters such as
``filter_table_part`` would select different objects once the robot has moved them.
"""
from __future__ import annotations

import logging
import math
from typing import Any, Callable, Mapping

from muble import Answer, ConfigError, Instruction, Outcome, PlanningError, SceneGraph
from muble.core.physical_properties import Derived, named
from muble.programs.program import QUERY_STEPS, execute, stack_pairs

from muble_plugins.common.geometry import broken, on_table_part, rests_on

log = logging.getLogger(__name__)

def recorded_final(instruction: Instruction, scene: SceneGraph) -> Any:
    """The final step's target: its recorded output, or the program run on ``scene`` with true weights."""
    final = instruction.program[-1].get("output")
    if final is not None:
        return final
    return execute(instruction.program, scene, weights="ground_truth").final


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def tolerance_check(name: str):
    """The answer check of the registered property ``name`` that has no check of its own
    (``Property.answer_check``): the answer gives each queried object its value, a list in the program's object
    order or a mapping of object id to value (``ids`` are the queried objects), each within the property's
    tolerance (``Property.answer_tolerance``). A value set against the wrong object fails."""

    def match(answer: Any, expected: list[float], ids: list[int] | None = None) -> bool:
        return _values_match(answer, expected, ids, named(name).answer_tolerance)

    match.__name__ = f"{name}_match"
    return match


weights_match = tolerance_check("weight")  # within 2 g or 2 %, the larger (the weight's record)
stiffness_match = tolerance_check("stiffness")
friction_match = tolerance_check("friction")
com_offset_match = tolerance_check("com_offset")


def rattles_match(answer: Any, expected: list[bool], ids: list[int] | None = None) -> bool:
    """The answer says of each queried object whether it rattles (a list of yes/no in the program's order, or a
    mapping of object id to yes/no); yes/no may be booleans or the words "yes"/"no"."""
    words = {"yes": True, "no": False, "true": True, "false": False}

    def yes_no(v: Any) -> float | None:
        if isinstance(v, bool):
            return float(v)
        return float(words[v.strip().lower()]) if isinstance(v, str) and v.strip().lower() in words else None

    values = answer.value if isinstance(answer, Answer) else answer
    if isinstance(values, dict):
        values = {k: yes_no(v) for k, v in values.items()}
    elif isinstance(values, (list, tuple)):
        values = [yes_no(v) for v in values]
    else:
        values = yes_no(values)
    return _values_match(values, [float(e) for e in expected], ids, lambda e: 0.0)


# The answer check of each query step (``muble.programs.program.QUERY_STEPS``), by the property it asks for: the
# registered record's own, or its tolerance.
ANSWER_CHECKS: Mapping[str, Callable[..., bool]] = Derived(
    lambda props: {n: p.answer_check or tolerance_check(n) for n, p in props.items()})


def _values_match(answer: Any, expected: list[float], ids: list[int] | None, tolerance) -> bool:
    values = answer.value if isinstance(answer, Answer) else answer
    if isinstance(values, dict):
        if ids is None:
            return False
        by_id: dict[int, Any] = {}
        for key, value in values.items():
            try:
                by_id[int(key)] = value
            except (TypeError, ValueError):
                return False
        if sorted(by_id) != sorted(ids):
            return False
        values = [by_id[i] for i in ids]
    if isinstance(values, (int, float)) and not isinstance(values, bool) and len(expected) == 1:
        values = [values]
    if not isinstance(values, (list, tuple)) or len(values) != len(expected):
        return False
    got = [_number(v) for v in values]
    return all(g is not None and abs(g - e) <= tolerance(e) for g, e in zip(got, expected))


def queried_ids(instruction: Instruction, scene: SceneGraph) -> list[int] | None:
    """The objects a query program (``query_weight``, ``query_friction`` …) measures, in its order: the recorded
    output of the step before, or the program run on ``scene``."""
    if len(instruction.program) < 2:
        return None
    before = instruction.program[-2].get("output")
    if before is None:
        before = execute(instruction.program, scene, weights="ground_truth").outputs[-2]
    if isinstance(before, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in before):
        return list(before)
    return None


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
        if kind in QUERY_STEPS:
            match = ANSWER_CHECKS[QUERY_STEPS[kind]]
            ok = answer is not None and match(answer, target, queried_ids(instruction, scene))
            return Outcome.SUCCESS if ok else Outcome.INCORRECT_ANSWER
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

"""What the learned planner sees: per-token state vectors built from the observed scene and the program's current
sub-goal, and the action vocabulary it chooses from. No PyTorch here (NumPy only), so the roll-outs that make the
training data and the agent share one featuriser.

A decision is made over a token sequence: one goal token (the sub-goal's kind and the arm's state), one token per
object in scene order, one per table part (``muble.core.types.TABLE_PARTS``) and a "none" token (``lower``
without a target: put the held object down where it is). The network outputs a primitive class and a pointer to
one token; primitives without a target ignore the pointer.

The sub-goal comes from running the program on the observed scene with what was measured so far
(``muble.programs.program.execute`` in ``"measured"`` mode): objects still to measure (weigh, squeeze, push,
balance or shake: the sub-goal's kind is the primitive that measures the property), an answer, an object to hold
up, objects to put on a table part, or stack pairs. The features mark which objects the sub-goal is
about and which of them already meet it; which primitive to call on which token is the network's choice.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from muble import ActionCall, Answer, Observation, SceneGraph
from muble.core.errors import PlanningError
from muble.core.observation import MEASURED_EXTRA
from muble.core.symbolic import ArmState, over
from muble.core.types import TABLE_PARTS
from muble.programs.program import QUANTITIES, QUERY_STEPS, execute, stack_pairs, table_parts_of

from muble_plugins.common.books import Known, book, fill_known
from muble_plugins.common.geometry import on_table_part, rests_on, upright
from muble_plugins.common.symbolic import (APPROACH, BALANCE, GRASP, LIFT, LOWER, MOVE, PUSH, RELEASE, SHAKE,
                                           SQUEEZE, WEIGH)

STOP = "stop"  # answer (query programs) and stop
# The primitives the planner chooses from: the motions and the measuring primitive of every hidden property
# registered when this module is imported (``muble.core.physical_properties.registered``: MuBlE's own five give the
# built-in classes; a package's property adds its primitive before ``stop``), then stop. A checkpoint records the
# classes and properties it was trained with (``layout``) and is refused under others.
_BUILTIN_CLASSES = (MOVE, APPROACH, GRASP, LIFT, WEIGH, LOWER, RELEASE, SQUEEZE, PUSH, BALANCE, SHAKE)
CLASSES = (*_BUILTIN_CLASSES, *dict.fromkeys(q.primitive for q in QUANTITIES.values()
                                             if q.primitive not in _BUILTIN_CLASSES), STOP)
# Which tokens each class may point at: objects, table parts, the none token; classes absent take no target.
TARGET_KINDS: dict[str, tuple[str, ...]] = {
    MOVE: ("object", "part"),
    APPROACH: ("object",),
    GRASP: ("object",),
    LOWER: ("object", "part", "none"),
}
MEASURE_KINDS = tuple(q.verb for q in QUANTITIES.values())  # a measuring sub-goal's kind: the primitive's name
GOAL_KINDS = (*MEASURE_KINDS, "answer", "pick_up", "move_to", "stack", "unknown")
IGNORE = -100  # pointer label of a class without a target

# Token layout: type indicators, then object features, then part features, then the goal token's features.
TOKEN_TYPES = ("goal", "object", "part", "none")
OBJECT_FEATURES = (
    "in_hand", "raised", "approached", "gripper_over", *(f"{q}_known" for q in QUANTITIES),
    "pending", "pending_rank", "primary", "secondary", "goal_object", "goal_rank",
    "on_goal", "at_destination", "upright", "stack_position", "stack_base_of_primary", "queried",
    "held_and_pending", "in_dest_part",
)
PART_FEATURES = tuple(f"part_{p}" for p in TABLE_PARTS) + ("destination",)
GOAL_FEATURES = tuple(f"kind_{k}" for k in GOAL_KINDS) + (
    "holding", "held_raised", "last_failed", "goal_met", "held_is_primary", "held_is_goal", "objects",
    "answer_ready",
)
_OFF_OBJ = len(TOKEN_TYPES)
_OFF_PART = _OFF_OBJ + len(OBJECT_FEATURES)
_OFF_GOAL = _OFF_PART + len(PART_FEATURES)
FEATURE_DIM = _OFF_GOAL + len(GOAL_FEATURES)
_OBJ = {name: _OFF_OBJ + k for k, name in enumerate(OBJECT_FEATURES)}
_PART = {name: _OFF_PART + k for k, name in enumerate(PART_FEATURES)}
_GOAL = {name: _OFF_GOAL + k for k, name in enumerate(GOAL_FEATURES)}


@dataclass
class SubGoal:
    """The program's current sub-goal on the observed scene."""

    kind: str
    pending: tuple[int, ...] = ()  # objects whose property the sub-goal's kind measures
    primary: int | None = None  # the object the sub-goal acts on now (move, stack: the first unmet one)
    secondary: int | None = None  # the stack base the primary goes on
    part: str | None = None  # move_to's table part
    goal_objects: list[int] = field(default_factory=list)  # every object the goal is about, in program order
    met: set[int] = field(default_factory=set)  # goal objects already where the goal wants them
    stack_order: list[int] = field(default_factory=list)  # bottom first
    answer: list | None = None  # query programs, once every needed value is measured


def subgoal(program: list[dict], scene: SceneGraph, known: Known) -> SubGoal:
    """The current sub-goal; raises ``PlanningError`` when the program cannot run on the scene."""
    trace = execute(program, scene, weights="measured", known=known)
    if trace.pending:
        return SubGoal(QUANTITIES[trace.pending_property].verb, pending=tuple(trace.pending))
    final_step = program[-1]
    kind, result = final_step["type"], trace.final
    arm = ArmState.of(scene)
    if kind in QUERY_STEPS:
        queried = list(trace.outputs[-2]) if len(trace.outputs) >= 2 and isinstance(trace.outputs[-2], list) else []
        return SubGoal("answer", goal_objects=queried, answer=list(result))
    if kind == "pick_up":
        target = result[0]
        met = {target} if arm.held == target and arm.raised else set()
        return SubGoal("pick_up", primary=target, goal_objects=[target], met=met)
    if kind == "move_to":
        part = final_step["input_value"]
        met = {i for i in result if on_table_part(scene.object(i), part, scene)}
        primary = next((i for i in result if i not in met), None)
        return SubGoal("move_to", primary=primary, part=part, goal_objects=list(result), met=met)
    if kind == "stack":
        pairs = stack_pairs(result)
        order = [pairs[0][1]] + [top for top, _ in pairs] if pairs else []
        met: set[int] = set()
        primary = secondary = None
        for top, base in pairs:
            if rests_on(scene.object(top), scene.object(base)):
                met.add(top)
            elif primary is None:
                primary, secondary = top, base
        return SubGoal("stack", primary=primary, secondary=secondary, goal_objects=order, met=met,
                       stack_order=order)
    return SubGoal("unknown")


def known_view(observation: Observation, known: Known, last: ActionCall | None) -> SceneGraph:
    """The observed scene with this agent's measurements filled in and, after a failed primitive, the hover and
    grasp-pose flags cleared (the hand is not where the plan left it); a world that reports no hover flags has
    them filled in from the last primitive. The same bookkeeping as the oracle's, so its labels fit."""
    # A copy deep enough for what is changed here (weights and flags), shallow elsewhere: deep copies of whole
    # scenes were most of a roll-out's time.
    scene = dataclasses.replace(observation.scene, objects=[
        dataclasses.replace(o, extra=dict(o.extra)) for o in observation.scene.objects])
    fill_known(scene, known, last, observation.last_result)
    return scene


def _rank(items: list[int] | tuple[int, ...], obj_id: int) -> float:
    """Position of ``obj_id`` in ``items`` scaled to (0, 1] (first: 1/4 … a fixed scale, so counts do not
    change what a rank means); 0 when absent."""
    return (items.index(obj_id) + 1) / 4.0 if obj_id in items else 0.0


def features(program: list[dict], scene: SceneGraph, known: Known, last_failed: bool) -> tuple[np.ndarray, SubGoal]:
    """Token features (1 + objects + parts + 1, ``FEATURE_DIM``) for ``scene`` (already ``known_view``) and the
    sub-goal they were built from."""
    goal = subgoal(program, scene, known)
    objects = scene.objects
    n = len(objects)
    x = np.zeros((1 + n + len(TABLE_PARTS) + 1, FEATURE_DIM), dtype=np.float32)
    arm = ArmState.of(scene)
    # Goal token.
    x[0, 0] = 1.0
    x[0, _GOAL[f"kind_{goal.kind}"]] = 1.0
    x[0, _GOAL["holding"]] = arm.held is not None
    x[0, _GOAL["held_raised"]] = arm.held is not None and arm.raised
    x[0, _GOAL["last_failed"]] = last_failed
    unmet = [i for i in goal.goal_objects if i not in goal.met]
    x[0, _GOAL["goal_met"]] = goal.kind in ("pick_up", "move_to", "stack") and not unmet
    x[0, _GOAL["held_is_primary"]] = arm.held is not None and arm.held == goal.primary
    x[0, _GOAL["held_is_goal"]] = arm.held is not None and arm.held in goal.goal_objects
    x[0, _GOAL["objects"]] = n / 10.0
    x[0, _GOAL["answer_ready"]] = goal.answer is not None
    # Object tokens.
    for k, o in enumerate(objects):
        row = x[1 + k]
        row[1] = 1.0
        row[_OBJ["in_hand"]] = bool(o.extra.get("in_hand"))
        row[_OBJ["raised"]] = bool(o.extra.get("in_hand")) and bool(o.extra.get("raised"))
        row[_OBJ["approached"]] = bool(o.extra.get("approached"))
        row[_OBJ["gripper_over"]] = bool(o.extra.get("gripper_over"))
        row[_OBJ["weight_known"]] = o.weight is not None or o.id in known.get("weight", {})
        for name, key in MEASURED_EXTRA.items():
            row[_OBJ[f"{name}_known"]] = key in o.extra or o.id in known.get(name, {})
        row[_OBJ["pending"]] = o.id in goal.pending
        row[_OBJ["pending_rank"]] = _rank(goal.pending, o.id)
        row[_OBJ["primary"]] = o.id == goal.primary
        row[_OBJ["secondary"]] = o.id == goal.secondary
        row[_OBJ["goal_object"]] = o.id in goal.goal_objects
        row[_OBJ["goal_rank"]] = _rank(goal.goal_objects, o.id)
        row[_OBJ["on_goal"]] = o.id in goal.met
        row[_OBJ["upright"]] = upright(o)
        row[_OBJ["queried"]] = goal.kind == "answer" and o.id in goal.goal_objects
        row[_OBJ["held_and_pending"]] = arm.held == o.id and o.id in goal.pending
        if goal.stack_order:
            row[_OBJ["stack_position"]] = _rank(goal.stack_order, o.id)
        row[_OBJ["stack_base_of_primary"]] = o.id == goal.secondary
        if goal.part is not None:
            row[_OBJ["in_dest_part"]] = goal.part in table_parts_of(o, scene)
        if arm.held == o.id and o.id == goal.primary:
            if goal.kind == "move_to":
                row[_OBJ["at_destination"]] = goal.part in table_parts_of(o, scene)
            elif goal.kind == "stack" and goal.secondary is not None:
                row[_OBJ["at_destination"]] = arm.over == goal.secondary or over(o, scene.object(goal.secondary))
    # Table-part tokens, then the none token.
    for k, part in enumerate(TABLE_PARTS):
        row = x[1 + n + k]
        row[2] = 1.0
        row[_PART[f"part_{part}"]] = 1.0
        row[_PART["destination"]] = part == goal.part
    x[-1, 3] = 1.0
    return x, goal


def token_kinds(n_objects: int) -> list[str]:
    return ["goal"] + ["object"] * n_objects + ["part"] * len(TABLE_PARTS) + ["none"]


def target_mask(n_objects: int) -> np.ndarray:
    """(classes, tokens) booleans: which tokens each class may point at (classes without a target: none)."""
    kinds = token_kinds(n_objects)
    mask = np.zeros((len(CLASSES), len(kinds)), dtype=bool)
    for c, name in enumerate(CLASSES):
        allowed = TARGET_KINDS.get(name, ())
        mask[c] = [k in allowed for k in kinds]
    return mask


def encode(decision: ActionCall | Answer | None, scene: SceneGraph) -> tuple[int, int]:
    """(class, pointer token) of a decision; the pointer is ``IGNORE`` for classes without a target."""
    if decision is None or isinstance(decision, Answer):
        return CLASSES.index(STOP), IGNORE
    cls = CLASSES.index(decision.name)
    if decision.name not in TARGET_KINDS:
        return cls, IGNORE
    target = decision.params.get("target")
    n = len(scene.objects)
    if target is None:
        return cls, 1 + n + len(TABLE_PARTS)
    if isinstance(target, str):
        return cls, 1 + n + TABLE_PARTS.index(target)
    ids = [o.id for o in scene.objects]
    return cls, 1 + ids.index(int(target))


def decode(cls: int, pointer: int, scene: SceneGraph) -> ActionCall | None:
    """The primitive call of a (class, pointer) choice; None for stop."""
    name = CLASSES[cls]
    if name == STOP:
        return None
    if name not in TARGET_KINDS:
        return ActionCall(name)
    n = len(scene.objects)
    if pointer <= 0:
        raise PlanningError(f"the planner pointed at no token for {name}")
    if pointer <= n:
        return ActionCall(name, {"target": scene.objects[pointer - 1].id})
    if pointer <= n + len(TABLE_PARTS):
        return ActionCall(name, {"target": TABLE_PARTS[pointer - 1 - n]})
    return ActionCall(name)


def random_call(rng: np.random.Generator, scene: SceneGraph) -> ActionCall:
    """A uniformly random primitive (never stop) with a random target of a kind it takes."""
    name = CLASSES[int(rng.integers(len(CLASSES) - 1))]
    if name not in TARGET_KINDS:
        return ActionCall(name)
    mask = target_mask(len(scene.objects))[CLASSES.index(name)]
    choices = np.flatnonzero(mask)
    return decode(CLASSES.index(name), int(choices[int(rng.integers(len(choices)))]), scene)


@dataclass
class Memory:
    """What an agent keeps over an episode: its measurements, the last call and failures per target."""

    known: Known = field(default_factory=dict)  # property -> object id -> measured value
    last: ActionCall | None = None
    failures: dict[Any, int] = field(default_factory=dict)

    def observe(self, observation: Observation) -> bool:
        """Book the last primitive's result; True when it failed."""
        result = observation.last_result
        if self.last is None or result is None:
            return False
        if not result.success:
            key = self.last.params.get("target")
            self.failures[key] = self.failures.get(key, 0) + 1
            return True
        book(self.known, self.last, result, ArmState.of(observation.scene).held)
        return False


def observe_features(memory: Memory, program: list[dict], observation: Observation,
                     failed: bool) -> tuple[np.ndarray, SubGoal, SceneGraph]:
    scene = known_view(observation, memory.known, memory.last)
    x, goal = features(program, scene, memory.known, failed)
    return x, goal, scene


def layout() -> dict[str, list[str]]:
    """What a trained network's inputs and outputs mean: its classes and the hidden properties its features name."""
    return {"classes": list(CLASSES), "properties": [q for q in QUANTITIES]}


__all__ = ["CLASSES", "FEATURE_DIM", "IGNORE", "Memory", "STOP", "SubGoal", "decode", "encode", "features",
           "known_view", "observe_features", "random_call", "subgoal", "target_mask", "token_kinds"]

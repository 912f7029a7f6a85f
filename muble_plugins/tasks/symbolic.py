"""Primitive names and a symbolic world that applies their preconditions and effects to a scene graph.

The symbolic world is what ground-truth plans are rolled out against: it checks every precondition a real
primitive has (grasping needs approaching, weighing needs a lifted object, squeezing a grasped one …), reveals
a weight only when ``weigh`` runs and a stiffness only when ``squeeze`` does, and moves objects where ``lower``
would put them; like the physical ``lower``, it lets go of the object (``open_gripper`` is needed only to drop
an object that was grasped but not lifted). The flags it keeps in ``SceneObject.extra`` (``in_hand``,
``raised``, ``approached``, ``gripper_over``) are the ones the physical environment reports.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

from muble import ActionCall, ActionResult, Observation, SceneGraph, SceneObject, get_registry
from muble.core.observation import MEASURED_STIFFNESS, TOUCHING_TABLE, agent_view

from muble_plugins.tasks.geometry import free_spot, height

# The primitive plugins' registry names (muble_plugins/primitives): grasping and releasing are the gripper primitives.
MOVE, APPROACH, LIFT, WEIGH, LOWER = "move", "approach", "lift", "weigh", "lower"
GRASP, RELEASE, SQUEEZE = "close_gripper", "open_gripper", "squeeze"
PRIMITIVES = (MOVE, APPROACH, GRASP, LIFT, WEIGH, LOWER, RELEASE, SQUEEZE)
FLAGS = ("in_hand", "raised", "approached", "gripper_over")
LIFT_HEIGHT = 0.1  # metres above the resting pose while raised
ARRIVAL_TOLERANCE = 0.03  # metres between a carried object and its destination that count as arrived over it


def over(held: SceneObject, base: SceneObject) -> bool:
    """``held`` is within ``ARRIVAL_TOLERANCE`` of ``base`` about the vertical (carried over it, or standing on
    it)."""
    return math.hypot(held.position[0] - base.position[0], held.position[1] - base.position[1]) <= ARRIVAL_TOLERANCE


@dataclass
class ArmState:
    """The gripper's symbolic state read from a scene graph."""

    held: int | None
    raised: bool
    approached: int | None
    over: int | None

    @classmethod
    def of(cls, scene: SceneGraph) -> "ArmState":
        held = approached = over = None
        raised = False
        for o in scene.objects:
            if o.extra.get("in_hand"):
                held, raised = o.id, bool(o.extra.get("raised"))
            if o.extra.get("approached"):
                approached = o.id
            if o.extra.get("gripper_over"):
                over = o.id
        return cls(held, raised, approached, over)


class SymbolicWorld:
    """Applies primitive calls to a private copy of a scene graph; failed preconditions fail the action.

    Agents observe ``agent_view`` of it: weights and stiffnesses only once they weighed or squeezed them, no
    ground truth. Objects put down
    record what they stand on in ``extra["touching"]``, as the physical world reports contacts. Primitives other
    than the built-in ones act through their ``PrimitiveAction.symbolic_effect``.
    """

    def __init__(self, scene: SceneGraph):
        self.scene = copy.deepcopy(scene)
        for o in self.scene.objects:
            o.weight = None
            o.extra.pop(MEASURED_STIFFNESS, None)
            for flag in FLAGS:
                o.extra[flag] = False
        self.measured: dict[int, dict[str, float]] = {}  # what the agent measured this episode
        self.destination: list[float] | None = None  # a table point the held object was moved over
        self.steps = 0

    def _set(self, flag: str, obj: SceneObject | None) -> None:
        for o in self.scene.objects:
            o.extra[flag] = o is obj

    def _object(self, call: ActionCall) -> SceneObject:
        return self.scene.object(int(call.params["target"]))

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        return Observation(scene=agent_view(self.scene, self.measured), last_result=result, step=step)

    def ground_truth(self) -> SceneGraph:
        return self.scene

    def apply(self, call: ActionCall) -> ActionResult:
        self.steps += 1
        try:
            return self._apply(call)
        except (KeyError, ValueError, TypeError) as e:
            return ActionResult(False, failure_reason=f"{call}: bad parameters ({e})")

    def _apply(self, call: ActionCall) -> ActionResult:
        state = ArmState.of(self.scene)
        held = self.scene.object(state.held) if state.held is not None else None
        fail = lambda why: ActionResult(False, failure_reason=f"{call}: {why}")  # noqa: E731
        if call.name == MOVE:
            if held is not None and not state.raised:
                return fail("lift the held object before moving")
            self._set("approached", None)
            if isinstance(call.params.get("target"), str):  # a table part
                self._set("gripper_over", None)
                part = call.params["target"]
                self.destination = free_spot(self.scene, held, part) if held is not None else None
                xy = self.destination[:2] if self.destination else None
            else:
                target = self._object(call)
                self._set("gripper_over", target)
                self.destination = None
                xy = target.position[:2]
            if held is not None and xy is not None:
                # The lifted object travels with the gripper.
                held.position = held.position.copy()
                held.position[:2] = xy
            return ActionResult(True)
        if call.name == APPROACH:
            target = self._object(call)
            if held is not None or state.over != target.id:
                return fail("move over an object with an empty gripper before approaching it")
            self._set("approached", target)
            self._set("gripper_over", None)
            return ActionResult(True)
        if call.name == GRASP:
            target = self._object(call)
            if held is not None or state.approached != target.id or not target.pickupable:
                return fail("grasping needs an approached, pickupable object and an empty gripper")
            self._set("approached", None)
            self._set("in_hand", target)
            self.destination = None
            return ActionResult(True)
        if call.name == LIFT:
            if held is None or state.raised:
                return fail("lifting needs a grasped object resting on its support")
            held.extra["raised"] = True
            held.extra["touching"] = []
            held.position = held.position + [0.0, 0.0, LIFT_HEIGHT]
            return ActionResult(True)
        if call.name == WEIGH:
            if held is None or not state.raised:
                return fail("weighing needs a lifted object")
            held.weight = held.weight_gt
            self.measured.setdefault(held.id, {})["weight"] = held.weight_gt
            return ActionResult(True, measurement=held.weight_gt)
        if call.name == SQUEEZE:
            # As the physical primitive: any grasped object, lifted or still standing on its support.
            if held is None:
                return fail("nothing between the fingers to squeeze: grasp an object first")
            if held.stiffness is None:
                return fail(f"object {held.id} has no stiffness to measure")
            held.extra[MEASURED_STIFFNESS] = held.stiffness  # as the physical world's scene graph records it
            self.measured.setdefault(held.id, {})["stiffness"] = held.stiffness
            return ActionResult(True, measurement=held.stiffness)
        if call.name == LOWER:
            if held is None or not state.raised:
                return fail("lowering needs a lifted object")
            target = call.params.get("target")
            if isinstance(target, str) and self.destination is None:
                self.destination = free_spot(self.scene, held, target)
            elif target is not None and not isinstance(target, str) and state.over != int(target) and \
                    not over(held, self._object(call)):
                return fail(f"move over object {target} before lowering onto it")
            self._lower(held, state)
            # Lowering puts the object down and lets go; the hand retreats straight up, over it.
            held.extra["raised"] = False
            self._set("in_hand", None)
            self._set("gripper_over", held)
            return ActionResult(True)
        if call.name == RELEASE:
            if held is None or state.raised:
                return fail("lower the held object before releasing it")
            self._set("in_hand", None)
            self._set("gripper_over", held)
            return ActionResult(True)
        # Any other registered primitive acts through its own symbolic model (PrimitiveAction.symbolic_effect).
        return get_registry().create("primitive", call.name, call.params).symbolic_effect(self.scene)

    def _lower(self, held: SceneObject, state: ArmState) -> None:
        held.extra.pop("tilt_deg", None)  # set down upright, however it leaned before
        if state.over is not None and state.over != held.id:
            base = self.scene.object(state.over)
            held.position = base.position + [0.0, 0.0, height(base)]
            held.extra["touching"] = [base.id]
        elif self.destination is not None:
            held.position = held.position.copy()
            held.position[:2] = self.destination[:2]
            held.position[2] = self.destination[2]
            held.extra["touching"] = [TOUCHING_TABLE]
        else:
            held.position = held.position - [0.0, 0.0, LIFT_HEIGHT]
            held.extra.pop("touching", None)  # back where it stood, on what it stood on
        self.destination = None

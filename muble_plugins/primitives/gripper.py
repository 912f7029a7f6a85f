"""Gripper and measurement primitives: close (grasp), open (release), weigh, squeeze (their readings:
``muble_plugins.primitives.measure``)."""
from __future__ import annotations

import logging

from muble import ActionResult, Param, PrimitiveAction, SceneGraph
from muble.core.observation import MEASURED_STIFFNESS
from muble.core.symbolic import CARRIED_TO, ArmState, set_flag

from muble_plugins.primitives import measure as readings
from muble_plugins.primitives import tolerances as tol

logger = logging.getLogger(__name__)

GRIPPER_SETTLE = 0.6  # s for the fingers to travel fully and the weld to engage
GRIPPER_SETTLE_MAX = 1.2  # s at most, while no object is held yet


def close_on_object(env) -> int | None:
    """Close the fingers and wait for the grasp weld to engage; the object then held, or None."""
    env.close_gripper()
    env.hold(GRIPPER_SETTLE)
    waited = GRIPPER_SETTLE
    while env.held_object is None and waited < GRIPPER_SETTLE_MAX:
        # A linkage gripper's jaws may still be closing onto a thin part (a stem, a rim).
        env.hold(tol.STEP_SETTLE)
        waited += tol.STEP_SETTLE
    return env.held_object


class CloseGripper(PrimitiveAction):
    """Close the fingers; succeeds when they hold an object (the grasp weld engaged).

    With ``target`` (a scene id) it succeeds only if that object is the one held.
    """

    params = (Param("target", "object", doc="the object expected between the fingers"),)
    # What ``ActionResult.measurement`` holds (docs/agent_api.md), for a primitive that measures no property.
    reports = "the id of the object now held (also when it is not the target, which fails the call)"

    def execute(self, env) -> ActionResult:
        held = close_on_object(env)
        if held is None:
            return ActionResult(False, failure_reason="the fingers closed on nothing: approach an object first")
        target = self.arguments.get("target")
        if target is not None and held != int(target):
            return ActionResult(False, measurement=held,
                                failure_reason=f"grasped object {held} instead of object {target}")
        return ActionResult(True, measurement=held, info={"held_object": held})

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The approached object, if it can be picked up, is in the empty hand."""
        hand = ArmState.of(scene)
        target = scene.object(int(self.arguments["target"]))
        if hand.held is not None or hand.approached != target.id or not target.pickupable:
            return ActionResult(False, failure_reason="grasping needs an approached, pickupable object and an empty "
                                                      "gripper")
        set_flag(scene, "approached", None)
        set_flag(scene, "in_hand", target)
        target.extra.pop(CARRIED_TO, None)
        return ActionResult(True)


class OpenGripper(PrimitiveAction):
    """Open the fingers, releasing whatever they hold."""

    params = ()

    def execute(self, env) -> ActionResult:
        released = env.held_object
        env.open_gripper()
        env.hold(GRIPPER_SETTLE)
        return ActionResult(env.held_object is None, info={"released": released})

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The held object, standing on its support, is let go; the hand stays over it."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or hand.raised:
            return ActionResult(False, failure_reason="lower the held object before releasing it")
        set_flag(scene, "in_hand", None)
        set_flag(scene, "gripper_over", held)
        return ActionResult(True)


class _HeldMeasurement(PrimitiveAction):
    """A measurement of the object in the hand: fails with ``empty_hand`` when nothing is held, or with what
    ``unmeasurable`` says; otherwise returns what ``measure`` reads, in ``measure_unit``. ``reading`` is the
    measuring procedure itself (``reading(env, ...)``), which ``measure`` calls."""

    params = ()
    empty_hand = "nothing in the hand to measure"

    def execute(self, env) -> ActionResult:
        if env.held_object is None:
            return ActionResult(False, failure_reason=self.empty_hand)
        reason = self.unmeasurable(env)
        if reason is not None:
            return ActionResult(False, failure_reason=reason)
        value = self.measure(env)
        return ActionResult(True, measurement=value, info={"object": env.held_object, "unit": self.measure_unit})

    def unmeasurable(self, env) -> str | None:
        """Why the held object cannot be measured now, or None."""
        return None

    def measure(self, env) -> float:
        raise NotImplementedError


class Weigh(_HeldMeasurement):
    """Weight in grams of the object in hand, from the wrist force sensor minus the empty-hand tare."""

    measures = "weight"
    measure_unit = "g"
    reading = staticmethod(readings.weigh)
    empty_hand = "nothing in the hand to weigh: pick an object up first"

    def unmeasurable(self, env) -> str | None:
        if env.touches_support(env.held_object):
            # Whatever it rests on would carry part of its weight: the reading would be wrong, not just noisy.
            return "the held object still touches its support: lift it first"
        return None

    def measure(self, env) -> float:
        return readings.weigh(env)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The lifted object's weight is known: its ground truth, recorded as measured (``SceneObject.weight``)."""
        hand = ArmState.of(scene)
        held = hand.held_object(scene)
        if held is None or not hand.raised:
            return ActionResult(False, failure_reason="weighing needs a lifted object")
        held.weight = held.weight_gt
        return ActionResult(True, measurement=held.weight_gt)


class Squeeze(_HeldMeasurement):
    """Stiffness (N/m) of the object between the fingers, from force against finger displacement."""

    measures = "stiffness"
    measure_unit = "N/m"
    reading = staticmethod(readings.squeeze)
    empty_hand = "nothing between the fingers to squeeze: grasp an object first"

    def measure(self, env) -> float:
        return readings.squeeze(env)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """The grasped object's stiffness is known (lifted or still standing on its support, as in ``execute``):
        its ground truth, recorded as measured (``extra["stiffness_measured"]``)."""
        held = ArmState.of(scene).held_object(scene)
        if held is None:
            return ActionResult(False, failure_reason=self.empty_hand)
        if held.stiffness is None:
            return ActionResult(False, failure_reason=f"object {held.id} has no stiffness to measure")
        held.extra[MEASURED_STIFFNESS] = held.stiffness  # as the physical world's scene graph records it
        return ActionResult(True, measurement=held.stiffness)

"""``reweigh``: weigh the held object again with a reading independent of the last, in one call.

A weighing subtracts the tare taken with the empty hand before the grasp, and a real wrist sensor's bias drifts in
between (``muble.sim.sensor_noise``): reading the same grasp twice repeats the same error. An independent reading
needs a new zero with nothing in the hand. ``reweigh`` does what an agent would do in five calls (``lower`` where
the object is, ``approach`` it, which zeroes the sensor with the open hand over it, ``close_gripper``, ``lift``,
``weigh``), through the same primitives and so the same physics, as one primitive: measuring again then costs an
agent one decision, and a comparison that one reading leaves open can be decided by several.
"""
from __future__ import annotations

from muble import ActionResult, PlanningError, SceneGraph
from muble.core.symbolic import ArmState

from muble_plugins.primitives.approach import Approach
from muble_plugins.primitives.gripper import CloseGripper, Weigh
from muble_plugins.primitives.lift import Lift
from muble_plugins.primitives.lower import Lower


class Reweigh(Weigh):
    """Weight in grams of the held, lifted object, read anew: it is set down where it is, the open hand zeroes the
    wrist sensor over it, grasps it again and lifts it as before, then the force is read as ``weigh`` reads it.

    Leaves the hand as it found it (the object held up). Fails, with the step that failed named, when the object
    cannot be set down, grasped or lifted again; the world is then as that step left it (the object may stand on
    the table, the hand empty)."""

    empty_hand = "nothing in the hand to weigh again: pick an object up and weigh it first"

    def execute(self, env) -> ActionResult:
        held = env.held_object
        if held is None:
            return ActionResult(False, failure_reason=self.empty_hand)
        reason = self.unmeasurable(env)
        if reason is not None:
            return ActionResult(False, failure_reason=reason)
        for step in (Lower(), Approach(target=held), CloseGripper(target=held), Lift()):
            name = type(step).__name__.lower()
            try:
                result = step.execute(env)
            except PlanningError as error:
                return ActionResult(False, failure_reason=f"weighing again: could not {name} object {held}: {error}")
            if not result.success:
                return ActionResult(False, failure_reason=f"weighing again: {name} failed: {result.failure_reason}")
        return super().execute(env)

    def symbolic_effect(self, scene: SceneGraph) -> ActionResult:
        """As ``weigh``: the lifted object's weight is known (its ground truth); the hand holds it up as before."""
        hand = ArmState.of(scene)
        if hand.held is None or not hand.raised:
            return ActionResult(False, failure_reason="weighing again needs a lifted object")
        return super().symbolic_effect(scene)

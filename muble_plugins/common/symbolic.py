"""Primitive names and a symbolic world that applies primitives' preconditions and effects to a scene graph.

The symbolic world is what ground-truth plans are rolled out against. Every primitive, built-in or not, acts
there through its own ``PrimitiveAction.symbolic_effect``, written beside its physical execution: the built-in
ones check every precondition the real primitive has (grasping needs approaching, weighing needs a lifted
object, squeezing a grasped one …), reveal a weight only when ``weigh`` runs and a stiffness only when
``squeeze`` does, and move objects where ``lower`` would put them; like the physical ``lower``, the symbolic one
lets go of the object (``open_gripper`` is needed only to drop an object that was grasped but not lifted). The
flags they keep in ``SceneObject.extra`` (``muble.core.symbolic.FLAGS``) are the ones the physical environment
reports.
"""
from __future__ import annotations

import copy

from muble import ActionCall, ActionResult, Observation, SceneGraph, get_registry
from muble.core.errors import ConfigError
from muble.core.observation import MEASURED_EXTRA, agent_view
from muble.core.symbolic import FLAGS

# The primitive plugins' registry names (muble_plugins/primitives), as the tasks' planners call them: grasping
# and releasing are the gripper primitives.
MOVE, APPROACH, LIFT, WEIGH, LOWER = "move", "approach", "lift", "weigh", "lower"
GRASP, RELEASE, SQUEEZE = "close_gripper", "open_gripper", "squeeze"
PUSH, BALANCE, SHAKE = "push", "balance", "shake"
PRIMITIVES = (MOVE, APPROACH, GRASP, LIFT, WEIGH, LOWER, RELEASE, SQUEEZE, PUSH, BALANCE, SHAKE)


class SymbolicWorld:
    """Applies primitive calls to a private copy of a scene graph through each primitive's
    ``PrimitiveAction.symbolic_effect``; failed preconditions fail the action, the reason prefixed with the call.

    Agents observe ``agent_view`` of it: weights and stiffnesses only once they weighed or squeezed them, no
    ground truth. Objects put down record what they stand on in ``extra["touching"]``, as the physical world
    reports contacts.
    """

    def __init__(self, scene: SceneGraph):
        self.scene = copy.deepcopy(scene)
        for o in self.scene.objects:
            o.weight = None
            for key in MEASURED_EXTRA.values():
                o.extra.pop(key, None)
            for flag in FLAGS:
                o.extra[flag] = False
        self.steps = 0

    @property
    def measured(self) -> dict[int, dict[str, float]]:
        """What the agent measured this episode, by object id: the weights and other properties the scene records
        as measured (``MEASURED_EXTRA``; the world starts with none)."""
        found: dict[int, dict[str, float]] = {}
        for o in self.scene.objects:
            if o.weight is not None:
                found.setdefault(o.id, {})["weight"] = o.weight
            for name, key in MEASURED_EXTRA.items():
                if key in o.extra:
                    found.setdefault(o.id, {})[name] = o.extra[key]
        return found

    def observe(self, result: ActionResult | None, step: int) -> Observation:
        return Observation(scene=agent_view(self.scene, self.measured), last_result=result, step=step)

    def ground_truth(self) -> SceneGraph:
        return self.scene

    def apply(self, call: ActionCall) -> ActionResult:
        self.steps += 1
        try:
            primitive = get_registry().create("primitive", call.name, call.params)
            result = primitive.symbolic_effect(self.scene)
        except (KeyError, ValueError, TypeError, ConfigError) as e:
            return ActionResult(False, failure_reason=f"{call}: bad parameters ({e})")
        if not result.success and result.failure_reason:
            result.failure_reason = f"{call}: {result.failure_reason}"
        return result

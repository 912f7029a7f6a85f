"""The books an agent keeps on what it observed, and how it retries a failed primitive: the oracle
(``muble_plugins.agents.oracle``) and the learned planner (``muble_plugins.learned``) keep them alike."""
from __future__ import annotations

from muble import ActionCall, ActionResult, SceneGraph, get_registry
from muble.core.observation import MEASURED_EXTRA, plain_measurement
from muble.core.symbolic import ArmState

from muble_plugins.common.symbolic import APPROACH, MOVE


Known = dict[str, dict[int, object]]  # property (``PrimitiveAction.measures``) -> object id -> measured value


def book(known: Known, last: ActionCall | None, result: ActionResult | None, held: int | None) -> None:
    """Book the measurement a successful measuring primitive (``last``) made of the ``held`` object."""
    if last is None or result is None or not result.success or held is None or result.measurement is None:
        return
    prop = get_registry().measures(last.name)
    if prop is not None:
        known.setdefault(prop, {})[held] = plain_measurement(result.measurement)


def fill_known(scene: SceneGraph, known: Known, last: ActionCall | None, result: ActionResult | None) -> None:
    """Fill an agent's copy of the observed ``scene`` with what it knows: the weights and other properties it
    measured (``known``), and the gripper's hover state. After a failed primitive (``result`` of ``last``) the hover
    and grasp-pose flags are cleared, so the plan starts over from hovering (a failed grasp or put-down leaves the
    hand where it should not stay); a world that reports no hover flags has them filled in from the last primitive.
    The oracle and the learned planner keep the same books, so the planner's labels fit."""
    weights = known.get("weight", {})
    for o in scene.objects:
        if o.weight is None and o.id in weights:
            o.weight = weights[o.id]
        for name, key in MEASURED_EXTRA.items():
            if key not in o.extra and o.id in known.get(name, {}):
                o.extra[key] = known[name][o.id]
    reported = any("gripper_over" in o.extra or "approached" in o.extra for o in scene.objects)
    if last is not None and result is not None and not result.success:
        for o in scene.objects:
            o.extra["approached"] = o.extra["gripper_over"] = False
    elif not reported and last is not None and result is not None:
        target = last.params.get("target")
        held = ArmState.of(scene).held
        for o in scene.objects:
            o.extra["gripper_over"] = last.name == MOVE and o.id == target
            o.extra["approached"] = last.name == APPROACH and held is None and o.id == target


RETRY_LIMIT = 16  # the highest ``attempt`` the built-in primitives take


def primitive_params(name: str) -> set[str]:
    """Names of the parameters the registered primitive ``name`` declares (empty if unknown)."""
    from muble.core.params import specs

    registry = get_registry()
    if name not in registry.names("primitive"):
        return set()
    return {p.name for p in specs(registry.get("primitive", name).record.factory.params)}

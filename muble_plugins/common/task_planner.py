"""Ground-truth action planning by backward chaining from the program's goal.

The program, run on the observed scene with the hidden properties measured so far, either asks for a
measurement (a sub-goal: weigh, squeeze, push, balance or shake those objects) or yields the goal: an answer, an
object held up, objects on a table part, or a stack. Each goal expands backwards into the primitives whose
preconditions lead to it: placing needs a lifted object, lifting needs grasping, grasping needs approaching,
approaching needs the gripper over the object; weighing, balancing and shaking need a lifted object, squeezing
and pushing only a grasped one standing where it is (``MEASURE``). Planning always starts from the observed
state, so the oracle can replan after every primitive.

An agent whose copy of the scene carries a ``Certainty`` (``muble_plugins.common.books``) has every comparison of
measured values checked against its readings' scatter; one not decided yet is a sub-goal too: measure the less
certain object again (``measure_again``), with a reading independent of the ones before.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

from muble import ActionCall, Answer, PlanningError, SceneGraph
from muble.core import physical_properties
from muble.core.physical_properties import Derived, Property
from muble.core.symbolic import ArmState, over
from muble.programs.program import QUERY_STEPS, execute, stack_pairs, table_parts_of

from muble_plugins.common.books import CERTAINTY, Certainty
from muble_plugins.common.geometry import on_table_part, rests_on, upright
from muble_plugins.common.symbolic import APPROACH, GRASP, LIFT, LOWER, MOVE, RELEASE


@dataclass
class Plan:
    """What to do next: ``actions`` (possibly empty) and, for queries, the ``answer`` once known."""

    actions: list[ActionCall]
    answer: Answer | None = None

    @property
    def done(self) -> bool:
        return not self.actions


def hold_up(obj_id: int, arm: ArmState) -> list[ActionCall]:
    """Primitives that leave ``obj_id`` grasped and lifted, starting from ``arm``."""
    if arm.held == obj_id:
        return [] if arm.raised else [ActionCall(LIFT)]
    return grasp(obj_id, arm) + [ActionCall(LIFT)]


def grasp(obj_id: int, arm: ArmState) -> list[ActionCall]:
    """Primitives that leave ``obj_id`` grasped (lifted or not), starting from ``arm``."""
    if arm.held == obj_id:
        return []
    actions: list[ActionCall] = []
    over, approached = arm.over, arm.approached
    if arm.held is not None:
        # Put the other object back down where it is held (lowering lets go; the hand stays over it).
        actions += put_down(arm)
        over, approached = arm.held, None
    if approached != obj_id:
        if over != obj_id:
            actions.append(ActionCall(MOVE, {"target": obj_id}))
        actions.append(ActionCall(APPROACH, {"target": obj_id}))
    return actions + [ActionCall(GRASP, {"target": obj_id})]


def put_down(arm: ArmState) -> list[ActionCall]:
    """Leave the gripper empty, setting a held object down where it is."""
    if arm.held is None:
        return []
    return [ActionCall(LOWER)] if arm.raised else [ActionCall(RELEASE)]


def _carried_to(scene: SceneGraph, obj_id: int, arm: ArmState, base_id: int) -> bool:
    """The object is in the gripper and already carried over ``base_id`` (or standing on it)."""
    if arm.held != obj_id:
        return False
    if arm.over == base_id:
        return True
    return over(scene.object(obj_id), scene.object(base_id))


def _deliver(scene: SceneGraph, obj_id: int, arrived: bool, destination: int | str, arm: ArmState) -> list[ActionCall]:
    """Carry ``obj_id`` to ``destination`` (an object id or a table part) and set it down there (``lower``
    lets go). An object grasped where it belongs but not lifted is just released if it stands upright; leaning
    there (a mug tipped against a bowl's rim, a can fallen over) it is lifted and set down again."""
    lower = ActionCall(LOWER, {"target": destination})
    if arrived:
        if arm.raised:
            return [lower]
        if upright(scene.object(obj_id)):
            return [ActionCall(RELEASE)]
        return [ActionCall(LIFT), lower]
    return hold_up(obj_id, arm) + [ActionCall(MOVE, {"target": destination}), lower]


def place_at(scene: SceneGraph, obj_id: int, part: str, arm: ArmState) -> list[ActionCall]:
    arrived = arm.held == obj_id and part in table_parts_of(scene.object(obj_id), scene)
    return _deliver(scene, obj_id, arrived, part, arm)


def place_on(scene: SceneGraph, obj_id: int, base_id: int, arm: ArmState) -> list[ActionCall]:
    return _deliver(scene, obj_id, _carried_to(scene, obj_id, arm, base_id), base_id, arm)


def _measuring(prop: Property):
    """The primitives that measure ``prop`` of an object from the arm's state: the hand brought to what the
    property needs (``Property.needs``), then its primitive."""
    measure = ActionCall(prop.primitive)
    if prop.needs == "held":
        return lambda obj_id, arm: hold_up(obj_id, arm) + [measure]
    if prop.needs == "standing":
        return lambda obj_id, arm: [ActionCall(LOWER)] if arm.held == obj_id and arm.raised else \
            grasp(obj_id, arm) + [measure]
    return lambda obj_id, arm: grasp(obj_id, arm) + [measure]


# How each hidden property is measured (the registered records: ``Property.primitive`` and ``needs``): the
# primitives that measure it of an object, from the arm's state.
MEASURE: Mapping[str, Callable[[int, ArmState], list[ActionCall]]] = Derived(
    lambda props: {name: _measuring(p) for name, p in props.items()})


def measure_again(prop: str, obj_id: int, arm: ArmState, certainty: Certainty) -> list[ActionCall]:
    """Measure ``obj_id``'s ``prop`` again, independently of the readings before. Weighing subtracts the tare that
    approaching takes with the empty hand, and the sensor's drift since that tare is what made the last reading err:
    an object in the hand that was measured since the hand last approached (``Certainty.read_since_approach``) is
    measured again by the property's own primitive for that (``Property.again``: ``reweigh``), where it has one and
    the hand is as its measuring primitive left it; else it is first set down where it is, then measured as the
    first time (approached, grasped, ...)."""
    if arm.held == obj_id and certainty.read_since_approach == obj_id:
        record = physical_properties.named(prop)
        if record.again is not None and (arm.raised or record.needs != "held"):
            return [ActionCall(record.again)]
        return put_down(arm) + MEASURE[prop](obj_id, ArmState(None, False, None, obj_id))
    return MEASURE[prop](obj_id, arm)


def _closest(pending: tuple[int, ...], arm: ArmState) -> int:
    """Of objects to measure again, the one the hand holds, is at or is over (least motion), else the first."""
    for obj_id in (arm.held, arm.approached, arm.over):
        if obj_id is not None and obj_id in pending:
            return obj_id
    return pending[0]


def plan_next(program: list[dict], scene: SceneGraph, known_weights: dict[int, float] | None = None,
              arm: ArmState | None = None, known_stiffness: dict[int, float] | None = None) -> Plan:
    """The remaining primitives for ``program`` from the observed ``scene`` (empty when the goal holds).

    ``arm`` overrides the gripper state read from the scene's flags. A ``Certainty`` in ``scene.extra``
    (``books.CERTAINTY``) decides whether a comparison of measured values counts yet. Raises ``PlanningError`` when
    the program cannot run on the scene or the goal cannot be reached.
    """
    arm = arm or ArmState.of(scene)
    certainty = scene.extra.get(CERTAINTY)
    trace = execute(program, scene, weights="measured", known_weights=known_weights,
                    known_stiffness=known_stiffness,
                    recheck=certainty.measure_again if certainty is not None else None)
    if trace.again or trace.pending:
        prop = trace.pending_property
        if prop is None:
            raise RuntimeError(f"the program's trace lists objects {list(trace.pending)} to measure, but no "
                               "property")
        if trace.again:
            if certainty is None:
                raise RuntimeError("the program's trace asks to measure again, but the scene has no Certainty")
            return Plan(measure_again(prop, _closest(trace.pending, arm), arm, certainty))
        target = arm.held if arm.held in trace.pending else trace.pending[0]
        return Plan(MEASURE[prop](target, arm))
    final_step = program[-1]
    kind, result = final_step["type"], trace.final
    if kind in QUERY_STEPS:
        return Plan([], Answer(list(result)))
    if kind == "pick_up":
        return Plan(hold_up(result[0], arm))
    if kind == "move_to":
        part = final_step["input_value"]
        for obj_id in result:
            obj = scene.object(obj_id)
            if not on_table_part(obj, part, scene):
                return Plan(place_at(scene, obj_id, part, arm))
        return Plan(put_down(arm))
    if kind == "stack":
        for top, base in stack_pairs(result):
            if not rests_on(scene.object(top), scene.object(base)):
                return Plan(place_on(scene, top, base, arm))
        return Plan(put_down(arm))
    raise PlanningError(f"a program must end in {', '.join(QUERY_STEPS)}, pick_up, move_to or stack, not '{kind}'")


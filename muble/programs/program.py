"""The CLEVR-IEP program executor over a scene graph.

A SHOP-VRB2 program is a list of steps ``{type, input, input_value, output}``. Steps run as chains: ``scene``
starts a chain with every object id, each filter narrows the previous step's output, and ``stack`` collects the
final output of every chain before it (top of the stack first). ``filter_relate`` (left, right, front, behind)
turns the one object before it into the objects on that side of it (``related``). The recorded ``input`` field is informative
only; execution always follows the chain.

Hidden properties are known only once measured (``QUANTITIES``: weight, stiffness, friction, centre-of-mass
offset, loose contents): in ``"measured"`` mode a step that needs one of an object the agent has not measured
(``weight`` still ``None``, or no ``extra["<property>_measured"]``, ``muble.core.observation.MEASURED_EXTRA``)
stops execution and reports those objects as measurement sub-goals (``ProgramTrace.pending``). In
``"ground_truth"`` mode the values come from the scene's ground truth (``weight_gt``, ``stiffness``, the
``muble.core.physical_properties`` keys), as generation and the reference checks need.

Measured values may be uncertain (a noisy sensor): ``execute(..., recheck=...)`` hands every comparison a filter or
an order makes (the pairs of objects whose order decided its output) to ``recheck``, which names the objects to
measure again before the comparison counts; the trace then reports them as pending with ``again`` set.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from muble.core import physical_properties as physical
from muble.core.errors import ConfigError, PlanningError, unknown_name
from muble.core.scene import SceneGraph, SceneObject
from muble.core.types import TABLE_PARTS
from muble.stage.table import parts_at

WEIGHT_MODES = ("measured", "ground_truth")
# Attribute filters: step type -> SceneObject field.
ATTRIBUTE_FILTERS = {
    "filter_size": "size",
    "filter_colour": "colour",
    "filter_material": "material",
    "filter_shape": "shape",
    "filter_name": "name",
}
WEIGHT_SUPERLATIVES = ("heaviest", "lightest")
WEIGHT_ORDERS = ("ascending", "descending")
STIFFNESS_SUPERLATIVES = ("hardest", "softest")
STIFFNESS_ORDERS = WEIGHT_ORDERS  # ascending: softest first
FRICTION_SUPERLATIVES = ("least slippery", "most slippery")  # the largest friction coefficient first
COM_SUPERLATIVES = ("furthest off-centre", "most centred")  # the largest centre-of-mass offset first
RATTLE_VALUES = ("rattling", "silent")  # filter_rattles: the objects that rattle, or those that do not
# Spatial relations of ``filter_relate`` (the original SHOP-VRB2 words) and the scene direction each one follows
# (sign, direction name) when the scene has ``directions``; without them left is -y and front is +x, as the table
# parts are named (``muble.stage.table``).
RELATIONS = {"left": (1.0, "left"), "right": (-1.0, "left"), "front": (1.0, "front"), "behind": (-1.0, "front")}
_DEFAULT_DIRECTIONS = {"left": (0.0, -1.0), "front": (1.0, 0.0)}


def related(scene: SceneGraph, anchor: int, relation: str) -> list[int]:
    """The ids of the objects that are ``relation`` (left, right, front, behind) of object ``anchor``, in scene
    order: those whose position lies on that side of the anchor's along the scene's direction for it (as the
    original SHOP-VRB2 ``relationships`` are computed)."""
    if relation not in RELATIONS:
        raise PlanningError(unknown_name("relation", str(relation), list(RELATIONS)))
    sign, name = RELATIONS[relation]
    directions = scene.directions or {}
    axis = tuple(directions[name][:2]) if name in directions else _DEFAULT_DIRECTIONS[name]
    origin = scene.object(anchor).position
    return [o.id for o in scene.objects if o.id != anchor
            and sign * ((o.position[0] - origin[0]) * axis[0] + (o.position[1] - origin[1]) * axis[1]) > 0]


def table_parts_of(obj: SceneObject, scene: SceneGraph | None = None) -> frozenset[str]:
    """The named table parts an object stands in (``muble.stage.table.parts_at`` of its position).

    The scene's ``directions`` (unit vectors for left/front) orient the split when present.
    """
    directions = scene.directions if scene is not None else None
    return parts_at(obj.position[0], obj.position[1], directions)


@dataclass
class ProgramTrace:
    """The result of running a program: one output per executed step.

    ``pending`` lists the objects whose ``pending_property`` (a ``QUANTITIES`` name) must be measured before the
    step at ``len(outputs)`` can run; empty when the program ran to the end.
    """

    outputs: list[Any] = field(default_factory=list)
    steps: int = 0
    pending_property: str | None = None
    pending: tuple[int, ...] = ()
    again: bool = False  # the pending objects were measured, but a comparison among them is not decided yet

    @property
    def pending_weights(self) -> tuple[int, ...]:
        return self.pending if self.pending_property == "weight" else ()

    @property
    def pending_stiffness(self) -> tuple[int, ...]:
        return self.pending if self.pending_property == "stiffness" else ()

    @property
    def complete(self) -> bool:
        return not self.pending and len(self.outputs) == self.steps

    @property
    def final(self) -> Any:
        if self.pending:
            raise PlanningError(f"program stopped at step {len(self.outputs)}: "
                                f"{QUANTITIES[str(self.pending_property)].verb} objects {list(self.pending)} first")
        if not self.complete:
            raise PlanningError(f"program stopped at step {len(self.outputs)} of {self.steps}")
        return self.outputs[-1]


class _NeedMeasurement(Exception):
    """Internal: a step needs the ``quantity`` of objects ``ids`` that are not measured yet."""

    def __init__(self, quantity: str, ids: list[int], again: bool = False):
        self.quantity = quantity
        self.ids = tuple(ids)
        self.again = again


# What a caller asks of a comparison between measured values (``execute``'s ``recheck``): given the property and the
# pairs of objects whose order a step relied on, the objects to measure again before that order counts (empty: it
# is decided).
Recheck = Callable[[str, list[tuple[int, int]]], "tuple[int, ...] | list[int]"]


# A hidden property a program compares or asks for, known to an agent only once it measured it: the registered
# ``muble.core.physical_properties.Property`` records. Its program steps are ``filter_<name>``, ``order_<name>``
# and ``query_<name>``. ``truth`` reads the ground truth of an object (None: the scene gives none) as the value a
# query answers and filters and orders compare, ``measured`` what the agent measured of it as the primitive
# reported it (None: not yet), and ``reading`` turns such a report into that value (a centre of mass's [x, y] mm
# into its distance from the centre). ``superlatives`` are the words of ``filter_<name>``, the first picking the
# largest value; a property without them is a yes/no property whose ``filter_<name>`` keeps the objects that have
# it (``values``: the words for yes and no), and has no order.
Quantity = physical.Property
QUANTITIES: Mapping[str, physical.Property] = physical.Derived(dict)


class _Context:
    def __init__(self, scene: SceneGraph, weights: str, known: dict[str, dict[int, Any]],
                 recheck: Recheck | None = None):
        if weights not in WEIGHT_MODES:
            raise ConfigError(unknown_name("weight mode", weights, WEIGHT_MODES))
        self.scene = scene
        self.by_id = {o.id: o for o in scene.objects}
        self.ground_truth = weights == "ground_truth"
        self.known = known
        self.recheck = None if self.ground_truth else recheck
        self.chains: list[Any] = []

    def settle(self, quantity: Quantity, pairs: list[tuple[int, int]]) -> None:
        """Raise ``_NeedMeasurement`` (again) for the objects ``recheck`` wants measured again before the order of
        ``pairs`` counts."""
        if self.recheck is None or not pairs:
            return
        again = tuple(self.recheck(quantity.name, pairs))
        if again:
            raise _NeedMeasurement(quantity.name, list(again), again=True)

    def values(self, quantity: Quantity, ids: list[int]) -> list[Any]:
        """The ``quantity`` of objects ``ids``: ground truth, or what was measured (raises ``_NeedMeasurement``
        naming those not measured yet)."""
        if self.ground_truth:
            out = [quantity.truth(self.by_id[i]) for i in ids]
            missing = [i for i, v in zip(ids, out) if v is None]
            if missing:
                raise PlanningError(f"objects {missing} have no ground-truth {quantity.name}; a program that asks "
                                    f"for it needs a scene whose objects carry one")
            return out
        known = self.known.get(quantity.name, {})
        raw = [known[i] if i in known else quantity.measured(self.by_id[i]) for i in ids]
        out = [None if v is None else quantity.reading(v) for v in raw]
        missing = [i for i, v in zip(ids, out) if v is None]
        if missing:
            raise _NeedMeasurement(quantity.name, missing)
        return out


def _ids(value: Any, step: dict[str, Any], index: int) -> list[int]:
    if not isinstance(value, list) or not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise PlanningError(f"step {index} ({step.get('type')}) needs a list of object ids from the step before, "
                            f"got {value!r:.60}; put a 'scene' or filter step before it")
    return value


def _step_scene(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
    return [o.id for o in ctx.scene.objects]


def _attribute_filter(attribute: str) -> Callable:
    def run(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
        value = step.get("input_value")
        return [i for i in _ids(prev, step, index) if getattr(ctx.by_id[i], attribute) == value]

    return run


def _step_filter_table_part(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
    part = step.get("input_value")
    if part not in TABLE_PARTS:
        raise PlanningError(unknown_name("table part", str(part), TABLE_PARTS))
    return [i for i in _ids(prev, step, index) if part in table_parts_of(ctx.by_id[i], ctx.scene)]


def _step_filter_relate(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
    ids = _ids(prev, step, index)
    if len(ids) != 1:
        raise PlanningError(f"step {index} (filter_relate) relates to one object, but the steps before it give "
                            f"{len(ids)}: {ids}; describe the reference object uniquely")
    return related(ctx.scene, ids[0], str(step.get("input_value")))  # None: an unknown relation


def _quantity_steps(q: Quantity) -> dict[str, Callable]:
    """The filter, order and query steps of a measured quantity."""

    def filter_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
        ids = _ids(prev, step, index)
        which = step.get("input_value")
        words = q.superlatives or q.values
        if which not in words:
            raise PlanningError(unknown_name(f"{q.name} {'superlative' if q.superlatives else 'value'}", str(which),
                                             words))
        if not ids:
            return []
        measured = ctx.values(q, ids)
        if not q.superlatives:  # a yes/no property: keep the objects that have it (or that do not)
            want = which == q.values[0]
            return [i for i, v in zip(ids, measured) if bool(v) == want]
        pick = max if which == q.superlatives[0] else min
        chosen = pick(range(len(ids)), key=lambda k: measured[k])
        ctx.settle(q, [(ids[chosen], ids[k]) for k in range(len(ids)) if k != chosen])
        return [ids[chosen]]

    def order_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
        ids = _ids(prev, step, index)
        order = step.get("input_value")
        if order not in q.orders:
            raise PlanningError(unknown_name(f"{q.name} order", str(order), q.orders))
        measured = ctx.values(q, ids)
        ranked = sorted(range(len(ids)), key=lambda k: measured[k], reverse=order == "descending")
        ctx.settle(q, [(ids[a], ids[b]) for a, b in zip(ranked, ranked[1:])])
        return [ids[k] for k in ranked]

    def query_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[Any]:
        return list(ctx.values(q, _ids(prev, step, index)))

    steps = {f"filter_{q.name}": filter_step, f"query_{q.name}": query_step}
    if q.orders:
        steps[f"order_{q.name}"] = order_step
    return steps


QUANTITY_STEPS: Mapping[str, dict[str, Callable]] = physical.Derived(
    lambda props: {name: _quantity_steps(q) for name, q in props.items()})
QUERY_STEPS: Mapping[str, str] = physical.Derived(  # step -> the property it asks for
    lambda props: {f"query_{name}": name for name in props})


def _step_pass_targets(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
    # Action steps (pick_up, move_to) name their targets; the world changes only when the plan runs.
    # move_to may find nothing left to move (a "remove" that is done); pick_up always needs an object.
    ids = _ids(prev, step, index)
    if not ids and step["type"] == "pick_up":
        raise PlanningError(f"step {index} ({step['type']}) has no target: the filters before it match nothing")
    return list(ids)


def _step_stack(ctx: _Context, step: dict, prev: Any, index: int) -> list[list[int]]:
    chains = [list(c) for c in (*ctx.chains, prev)] if prev is not None else []
    if not chains or any(not c for c in chains):
        raise PlanningError(f"step {index} (stack) needs non-empty object chains before it, got {chains}")
    return chains


def stack_pairs(chains: list[list[int]]) -> list[tuple[int, int]]:
    """(top, base) pairs of a ``stack`` step's output, bottom pair first; the chains list the stack top first."""
    order = [i for chain in chains for i in chain]
    return [(order[k], order[k + 1]) for k in range(len(order) - 2, -1, -1)]


def stacked_pairs(program: list[dict[str, Any]]) -> list[tuple[int, int]]:
    """The (top, base) pairs a program ending in ``stack`` builds, bottom pair first, from the output its last
    step recorded (ground-truth weights; see ``Instruction.program``); empty for any other program."""
    if not program or program[-1].get("type") != "stack" or not program[-1].get("output"):
        return []
    return stack_pairs(program[-1]["output"])


STEP_TYPES: Mapping[str, Callable[[_Context, dict, Any, int], Any]] = physical.Derived(lambda props: {
    "scene": _step_scene,
    **{name: _attribute_filter(attr) for name, attr in ATTRIBUTE_FILTERS.items()},
    "filter_table_part": _step_filter_table_part,
    "filter_relate": _step_filter_relate,
    **{name: run for steps in QUANTITY_STEPS.values() for name, run in steps.items()},
    "pick_up": _step_pass_targets,
    "move_to": _step_pass_targets,
    "stack": _step_stack,
})
STIFFNESS_STEPS = frozenset(("filter_stiffness", "query_stiffness", "order_stiffness"))


def execute(program: list[dict[str, Any]], scene: SceneGraph, *, weights: str = "measured",
            known_weights: dict[int, float] | None = None,
            known_stiffness: dict[int, float] | None = None,
            known: dict[str, dict[int, Any]] | None = None, recheck: Recheck | None = None) -> ProgramTrace:
    """Run ``program`` on ``scene``.

    ``known`` adds measurements not yet written into the scene graph (property -> object id -> value, as the
    primitive reported it); ``known_weights`` (object id -> grams) and ``known_stiffness`` (N/m) are its weight
    and stiffness parts. ``recheck`` (measured mode only) is asked of every comparison of measured values: the
    objects it names are reported as pending, with ``again`` set.
    Raises ``PlanningError`` when the program cannot run on this scene (unknown object, no target) and
    ``ConfigError`` for an unknown step type.
    """
    values = {name: dict(v) for name, v in (known or {}).items()}
    values.setdefault("weight", {}).update(known_weights or {})
    values.setdefault("stiffness", {}).update(known_stiffness or {})
    ctx = _Context(scene, weights, values, recheck)
    trace = ProgramTrace(steps=len(program))
    prev: Any = None
    for index, step in enumerate(program):
        kind = step.get("type")
        run = STEP_TYPES.get(str(kind))
        if run is None:
            raise ConfigError(unknown_name("program step type", str(kind), list(STEP_TYPES)))
        if kind == "scene" and prev is not None and index > 0 and program[index - 1]["type"] != "stack":
            ctx.chains.append(prev)
        try:
            out = run(ctx, step, prev, index)
        except _NeedMeasurement as need:
            trace.pending_property, trace.pending, trace.again = need.quantity, need.ids, need.again
            return trace
        except KeyError as e:
            raise PlanningError(f"step {index} ({kind}) refers to object {e} that this scene lacks") from None
        if kind == "stack":
            ctx.chains = []
        trace.outputs.append(out)
        prev = out
    return trace


def _close(a: Any, b: Any, tol: float) -> bool:
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, tol) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return abs(a - b) <= tol
    return a == b


def outputs_match(program: list[dict[str, Any]], trace: ProgramTrace, tol: float = 1e-6) -> list[int]:
    """Indices of steps whose recorded ``output`` differs from the trace (empty when all agree)."""
    return [i for i, step in enumerate(program)
            if i >= len(trace.outputs) or not _close(step.get("output"), trace.outputs[i], tol)]

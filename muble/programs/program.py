"""The CLEVR-IEP program executor over a scene graph.

A SHOP-VRB2 program is a list of steps ``{type, input, input_value, output}``. Steps run as chains: ``scene``
starts a chain with every object id, each filter narrows the previous step's output, and ``stack`` collects the
final output of every chain before it (top of the stack first). ``filter_relate`` (left, right, front, behind)
turns the one object before it into the objects on that side of it (``related``). The recorded ``input`` field is informative
only; execution always follows the chain.

Weights and stiffnesses are known only once measured: in ``"measured"`` mode a step that needs the weight of an
object whose ``weight`` is still ``None`` (or the stiffness of one without ``extra["stiffness_measured"]``) stops
execution and reports those objects as measurement sub-goals (weigh them, or squeeze them). In ``"ground_truth"``
mode weights come from ``weight_gt`` and stiffnesses from ``stiffness`` (generation, reference checks).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from muble.core.errors import ConfigError, PlanningError, unknown_name
from muble.core.observation import MEASURED_STIFFNESS  # extra key of a stiffness the agent measured (N/m)
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

    ``pending_weights`` lists the objects whose weight must be measured (``pending_stiffness``: whose stiffness
    must be measured) before the step at ``len(outputs)`` can run; both are empty when the program ran to the end.
    """

    outputs: list[Any] = field(default_factory=list)
    pending_weights: tuple[int, ...] = ()
    steps: int = 0
    pending_stiffness: tuple[int, ...] = ()

    @property
    def complete(self) -> bool:
        return not self.pending_weights and not self.pending_stiffness and len(self.outputs) == self.steps

    @property
    def final(self) -> Any:
        if self.pending_weights:
            raise PlanningError(
                f"program stopped at step {len(self.outputs)}: weigh objects {list(self.pending_weights)} first"
            )
        if self.pending_stiffness:
            raise PlanningError(f"program stopped at step {len(self.outputs)}: squeeze objects "
                                f"{list(self.pending_stiffness)} first")
        if not self.complete:
            raise PlanningError(f"program stopped at step {len(self.outputs)} of {self.steps}")
        return self.outputs[-1]


class _NeedMeasurement(Exception):
    """Internal: a step needs unmeasured values; ``pending`` names the ``ProgramTrace`` field that lists them."""

    def __init__(self, pending: str, ids: list[int]):
        self.pending = pending
        self.ids = tuple(ids)


class _Context:
    def __init__(self, scene: SceneGraph, weights: str, known: dict[int, float] | None,
                 known_stiffness: dict[int, float] | None = None):
        if weights not in WEIGHT_MODES:
            raise ConfigError(unknown_name("weight mode", weights, WEIGHT_MODES))
        self.scene = scene
        self.by_id = {o.id: o for o in scene.objects}
        self.ground_truth = weights == "ground_truth"
        self.known = known or {}
        self.known_stiffness = known_stiffness or {}
        self.chains: list[Any] = []

    def stiffnesses(self, ids: list[int]) -> list[float]:
        if self.ground_truth:
            missing = [i for i in ids if self.by_id[i].stiffness is None]
            if missing:
                raise PlanningError(f"objects {missing} have no ground-truth stiffness; a program that compares "
                                    "stiffness needs a scene whose objects carry one")
            return [self.by_id[i].stiffness for i in ids]
        return _measured(ids, lambda i: self.known_stiffness.get(i, self.by_id[i].extra.get(MEASURED_STIFFNESS)),
                         "pending_stiffness")

    def weights(self, ids: list[int]) -> list[float]:
        if self.ground_truth:
            return [self.by_id[i].weight_gt for i in ids]
        return _measured(ids, lambda i: self.known.get(i, self.by_id[i].weight), "pending_weights")


def _measured(ids: list[int], read: Callable[[int], float | None], pending: str) -> list[float]:
    """The values ``read`` gives for ``ids``; raises ``_NeedMeasurement`` naming those not measured yet."""
    out = [read(i) for i in ids]
    missing = [i for i, v in zip(ids, out) if v is None]
    if missing:
        raise _NeedMeasurement(pending, missing)
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
    return related(ctx.scene, ids[0], step.get("input_value"))


def _measured_steps(quantity: str, values: str, superlatives: tuple[str, str],
                    orders: tuple[str, ...]) -> dict[str, Callable]:
    """The filter, order and query steps of a measured quantity (``values``: the ``_Context`` method that reads
    it); the first superlative picks the largest value."""

    def filter_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
        ids = _ids(prev, step, index)
        which = step.get("input_value")
        if which not in superlatives:
            raise PlanningError(unknown_name(f"{quantity} superlative", str(which), superlatives))
        if not ids:
            return []
        measured = getattr(ctx, values)(ids)
        pick = max if which == superlatives[0] else min
        return [ids[pick(range(len(ids)), key=lambda k: measured[k])]]

    def order_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[int]:
        ids = _ids(prev, step, index)
        order = step.get("input_value")
        if order not in orders:
            raise PlanningError(unknown_name(f"{quantity} order", str(order), orders))
        measured = getattr(ctx, values)(ids)
        ranked = sorted(range(len(ids)), key=lambda k: measured[k], reverse=order == "descending")
        return [ids[k] for k in ranked]

    def query_step(ctx: _Context, step: dict, prev: Any, index: int) -> list[float]:
        return list(getattr(ctx, values)(_ids(prev, step, index)))

    return {f"filter_{quantity}": filter_step, f"order_{quantity}": order_step, f"query_{quantity}": query_step}


_WEIGHT_STEP_TYPES = _measured_steps("weight", "weights", WEIGHT_SUPERLATIVES, WEIGHT_ORDERS)
_STIFFNESS_STEP_TYPES = _measured_steps("stiffness", "stiffnesses", STIFFNESS_SUPERLATIVES, STIFFNESS_ORDERS)


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


STEP_TYPES: dict[str, Callable[[_Context, dict, Any, int], Any]] = {
    "scene": _step_scene,
    **{name: _attribute_filter(attr) for name, attr in ATTRIBUTE_FILTERS.items()},
    "filter_table_part": _step_filter_table_part,
    "filter_relate": _step_filter_relate,
    **_WEIGHT_STEP_TYPES,
    **_STIFFNESS_STEP_TYPES,
    "pick_up": _step_pass_targets,
    "move_to": _step_pass_targets,
    "stack": _step_stack,
}
STIFFNESS_STEPS = frozenset(_STIFFNESS_STEP_TYPES)


def execute(program: list[dict[str, Any]], scene: SceneGraph, *, weights: str = "measured",
            known_weights: dict[int, float] | None = None,
            known_stiffness: dict[int, float] | None = None) -> ProgramTrace:
    """Run ``program`` on ``scene``.

    ``known_weights`` adds measurements not yet written into the scene graph (object id -> grams);
    ``known_stiffness`` likewise (object id -> N/m).
    Raises ``PlanningError`` when the program cannot run on this scene (unknown object, no target) and
    ``ConfigError`` for an unknown step type.
    """
    ctx = _Context(scene, weights, known_weights, known_stiffness)
    trace = ProgramTrace(steps=len(program))
    prev: Any = None
    for index, step in enumerate(program):
        kind = step.get("type")
        run = STEP_TYPES.get(kind)
        if run is None:
            raise ConfigError(unknown_name("program step type", str(kind), list(STEP_TYPES)))
        if kind == "scene" and prev is not None and index > 0 and program[index - 1]["type"] != "stack":
            ctx.chains.append(prev)
        try:
            out = run(ctx, step, prev, index)
        except _NeedMeasurement as need:
            setattr(trace, need.pending, need.ids)
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

"""The ten SHOP-VRB2 task templates: phrasings, scene constraints and program skeletons.

Each template enumerates its *options* for a scene: the object-level choices (which objects, which table part,
which weight superlative) that satisfy its constraints. Options are cheap tuples; the generator samples some and
only then picks descriptions and a phrasing. Weight-dependent constraints use the ground-truth weights, with a
margin so that a measured weight cannot swap the order.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

from muble.core.program import OPPOSITE_PART, table_parts_of

from muble_plugins.tasks.descriptions import SceneIndex
from muble_plugins.tasks.geometry import room_on_part

TABLE_PARTS = ("left", "right", "front", "back")
SUPERLATIVES = ("heaviest", "lightest")
MAX_STACK = 4  # objects in one "stack all" tower
MAX_COMPARED = 5  # objects weighed to find a heaviest/lightest one (keeps plans within 46 primitives)


@dataclass(frozen=True)
class Template:
    template_id: str
    task_id: str
    index: int  # template_overall_idx
    texts: tuple[str, ...]
    options: Callable[["OptionContext"], Iterator[tuple]]
    description: str
    # Checked only for the options the generator samples (dearer than the constraints in ``options``): whether
    # the objects the option puts down on a table part have room there.
    feasible: Callable[[tuple, "OptionContext"], bool] | None = None


@dataclass
class OptionContext:
    index: SceneIndex
    weight_margin: float

    def obj(self, i: int):
        return self.index.objects[i]

    def parts(self, i: int) -> frozenset[str]:
        return table_parts_of(self.index.objects[i], self.index.scene)

    def pickable_unique(self) -> list[int]:
        return [i for i in self.index.unique if self.obj(i).pickupable]

    def pickable_groups(self, max_size: int | None = None) -> list[tuple[int, ...]]:
        return [g for g in self.index.groups if all(self.obj(i).pickupable for i in g)
                and (max_size is None or len(g) <= max_size)]

    def room(self, movers: list[int], part: str) -> bool:
        """Whether the objects ``movers``, put down one after another on ``part``, all find room there."""
        return room_on_part(self.index.scene, [self.obj(i) for i in movers], part)

    def by_weight(self, group: tuple[int, ...]) -> list[int] | None:
        """Group ids heaviest first, or ``None`` when two weights are closer than the margin."""
        ranked = sorted(group, key=lambda i: -self.obj(i).weight_gt)
        gaps = [self.obj(a).weight_gt - self.obj(b).weight_gt for a, b in zip(ranked, ranked[1:])]
        return ranked if all(g >= self.weight_margin for g in gaps) else None

    def extreme(self, group: tuple[int, ...], which: str) -> int | None:
        ranked = sorted(group, key=lambda i: -self.obj(i).weight_gt)
        top, second = (ranked[0], ranked[1]) if which == "heaviest" else (ranked[-1], ranked[-2])
        if abs(self.obj(top).weight_gt - self.obj(second).weight_gt) < self.weight_margin:
            return None
        return top


def _measure_single(c: OptionContext) -> Iterator[tuple]:
    for o in c.pickable_unique():
        yield (o,)


def _measure_multi(c: OptionContext) -> Iterator[tuple]:
    for g in c.pickable_groups():
        yield (g,)


def _pick_up(c: OptionContext) -> Iterator[tuple]:
    for g in c.pickable_groups(MAX_COMPARED):
        for ws in SUPERLATIVES:
            if c.extreme(g, ws) is not None:
                yield (g, ws)


def _move_single(c: OptionContext) -> Iterator[tuple]:
    for o in c.pickable_unique():
        for tp in TABLE_PARTS:
            if tp not in c.parts(o):
                yield (o, tp)


def _remove(c: OptionContext) -> Iterator[tuple]:
    for g in c.index.groups:
        for tp in TABLE_PARTS:
            inside = [i for i in g if tp in c.parts(i)]
            if inside and all(c.obj(i).pickupable for i in inside):
                yield (g, tp)


def _move_weight(c: OptionContext) -> Iterator[tuple]:
    for g in c.pickable_groups(MAX_COMPARED):
        for ws in SUPERLATIVES:
            target = c.extreme(g, ws)
            if target is None:
                continue
            for tp in TABLE_PARTS:
                if tp not in c.parts(target):
                    yield (g, ws, tp)


def _room_move_single(option: tuple, c: OptionContext) -> bool:
    return c.room([option[0]], option[1])


def _room_remove(option: tuple, c: OptionContext) -> bool:
    group, part = option
    return c.room([i for i in group if part in c.parts(i)], OPPOSITE_PART[part])


def _room_move_weight(option: tuple, c: OptionContext) -> bool:
    group, ws, part = option
    return c.room([c.extreme(group, ws)], part)


def _stack_simple(c: OptionContext) -> Iterator[tuple]:
    bases = [i for i in c.index.unique if c.obj(i).stack_base]
    for o1 in c.pickable_unique():
        if c.obj(o1).stackable:
            for o2 in bases:
                if o2 != o1:
                    yield (o1, o2)


def _stack_weight(c: OptionContext) -> Iterator[tuple]:
    bases = [i for i in c.index.unique if c.obj(i).stack_base]
    for g in c.pickable_groups(MAX_COMPARED):
        for ws in SUPERLATIVES:
            top = c.extreme(g, ws)
            if top is None or not c.obj(top).stackable:
                continue
            for o2 in bases:
                if o2 not in g:
                    yield (g, ws, o2)


def _stack_three(c: OptionContext) -> Iterator[tuple]:
    tops = [i for i in c.pickable_unique() if c.obj(i).stackable]
    middles = [i for i in tops if c.obj(i).stack_base]
    bases = [i for i in c.index.unique if c.obj(i).stack_base]
    for o1 in tops:
        for o2 in middles:
            if o2 == o1:
                continue
            for o3 in bases:
                if o3 != o1 and o3 != o2:
                    yield (o1, o2, o3)


def _stack_order(c: OptionContext) -> Iterator[tuple]:
    for g in c.pickable_groups():
        if len(g) > MAX_STACK:
            continue
        ranked = c.by_weight(g)
        if ranked is None:
            continue
        if all(c.obj(i).stack_base for i in ranked[:-1]) and all(c.obj(i).stackable for i in ranked[1:]):
            yield (g,)


TEMPLATES: dict[str, Template] = {t.template_id: t for t in [
    Template("measure_weight_single", "measure_weight", 0, (
        "Measure the weight of the {O1}.",
        "What is the weight of the {O1}?",
        "How heavy is the {O1}?",
        "Find out how much the {O1} weighs.",
    ), _measure_single, "measure the weight of one object"),
    Template("measure_weight_multi", "measure_weight", 1, (
        "Measure the weight of all {O1s}.",
        "What is the weight of all {O1s}?",
        "Measure the weight of {O1s}.",
        "How much do all {O1s} weigh?",
    ), _measure_multi, "measure the weight of every object of a kind"),
    Template("pick_up_lightest", "pick_up", 2, (
        "Pick up the {WS} of all {O1s}.",
        "Pick up the {WS} of {O1s}.",
        "Lift the {WS} of all {O1s}.",
        "Find and pick up the {WS} of the {O1s}.",
    ), _pick_up, "pick up the heaviest or lightest object of a kind"),
    Template("move_single", "move", 3, (
        "Move the {O1} to the {TP} part of the table.",
        "Place the {O1} on the {TP} part of the table.",
        "Put the {O1} on the {TP} side of the table.",
    ), _move_single, "move one object to a table part", _room_move_single),
    Template("remove", "move", 4, (
        "Remove all {O1s} from the {TP} part of the table.",
        "Clean the {TP} part of the table from all {O1s}.",
        "Clear all {O1s} off the {TP} side of the table.",
    ), _remove, "remove every object of a kind from a table part", _room_remove),
    Template("move_weight", "move", 5, (
        "Place the {WS} of all {O1s} on the {TP} part of the table.",
        "Move the {WS} of {O1s} to the {TP} part of the table.",
        "Put the {WS} of the {O1s} on the {TP} side of the table.",
    ), _move_weight, "move the heaviest or lightest object of a kind to a table part", _room_move_weight),
    Template("stack_simple", "stack", 6, (
        "Stack the {O1} on the {O2}.",
        "Stack the {O1} on top of the {O2}.",
        "Put the {O1} on top of the {O2}.",
        "Place the {O1} on the {O2}.",
    ), _stack_simple, "stack one object on another"),
    Template("stack_weight", "stack", 7, (
        "Place the {WS} of all {O1s} on top of the {O2}.",
        "Stack the {WS} of {O1s} on the {O2}.",
        "Put the {WS} of the {O1s} on top of the {O2}.",
    ), _stack_weight, "stack the heaviest or lightest object of a kind on another object"),
    Template("stack_three", "stack", 8, (
        "Place the {O1} on top of the {O2} on the {O3}.",
        "Stack the {O1} on the {O2} on top of the {O3}.",
        "Stack the {O1} on top of the {O2} on top of the {O3}.",
    ), _stack_three, "build a stack of three given objects"),
    Template("stack_order", "stack", 9, (
        "Stack all {O1s} from heaviest to lightest.",
        "Stack {O1s} from the heaviest to the lightest.",
        "Make a stack of all {O1s} with the heaviest at the bottom.",
    ), _stack_order, "stack every object of a kind, heaviest at the bottom"),
]}

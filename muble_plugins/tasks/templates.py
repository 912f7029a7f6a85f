"""SHOP-VRB2 task templates: phrasings, scene constraints and program skeletons, read from template files.

The ten built-in templates are data (``shopvrb2_templates.yaml``, format in ``template_data``), and so are the
stiffness family (``stiffness_templates.yaml``) and the physical family (``physical_templates.yaml``: friction,
centre of mass, loose contents), which instructions get only when asked for by name. Each template
enumerates its *options* for a scene: the object-level choices (which objects, which table part, which weight
superlative) that satisfy its constraints. Options are cheap tuples; the generator samples some and only then
picks descriptions and a phrasing. Weight-dependent constraints use the ground-truth weights, with a margin so
that a measured weight cannot swap the order; the other measured quantities likewise, each with its margin
(``Property.margin``: at least twice the accuracy its primitive is held to).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Mapping

from muble.core.physical_properties import Derived
from muble.programs.descriptions import SceneIndex
from muble.programs.program import QUANTITIES, table_parts_of
from muble.stage.footprint import Outlines

from muble_plugins.common.geometry import room_on_part
from muble_plugins.tasks.template_data import DataTemplate, read_template_file

MAX_STACK = 4  # objects in one "stack all" tower (the built-in templates' max_count)
MAX_COMPARED = 5  # objects weighed to find a heaviest/lightest one (keeps plans within 46 primitives)
# The margin of each compared quantity but the weight (whose margin is the generator's ``weight_margin``), from its
# registered record (``Property.margin``/``margin_rel``): (relative: a fraction of the smaller | absolute: in the
# quantity's unit, margin).
MARGINS: Mapping[str, tuple[bool, float]] = Derived(lambda props: {
    n: (p.margin_rel is not None, p.margin_rel if p.margin_rel is not None else p.margin)
    for n, p in props.items() if p.compared})


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
    # (option, chosen descriptions) -> (text slots, program without outputs); text + slots -> instruction text
    build: Callable[[tuple, list], tuple[dict[str, str], list[dict]]] | None = None
    fill: Callable[[str, dict[str, str]], str] | None = None
    step_types: tuple[str, ...] = ()  # the types of its program's steps ("filter_weight", "order_weight" ...)


def _memo(method):
    """Cache a ranking method's result per arguments on the context (each is asked again for every table part or
    base an option pairs with it)."""
    name = method.__name__

    @functools.wraps(method)
    def cached(self, *args):
        key = (name, *args)
        if key not in self._ranked:
            self._ranked[key] = method(self, *args)
        return self._ranked[key]
    return cached


@dataclass
class OptionContext:
    index: SceneIndex
    weight_margin: float
    # The scene's object outlines for the room check, computed once per object (``Outlines``; a generator that
    # lists several templates' options for one scene hands each context the same memo).
    outlines: Outlines = field(default_factory=Outlines)
    # Close comparisons (``ShopVrb2TaskConfig.weight_gap_max_g``, ``weight_close_pairs``): of the pairs of weights a
    # template compares (an order's neighbours, a superlative's choice against each other candidate), at least
    # ``weight_close_pairs`` differ by at most ``weight_gap_max``; None: no bound.
    weight_gap_max: float | None = None
    weight_close_pairs: int = 1
    # Memos: the scene does not change while the options are listed.
    _parts: dict[int, frozenset[str]] = field(default_factory=dict)
    _ranked: dict[tuple, object] = field(default_factory=dict)

    def obj(self, i: int):
        return self.index.objects[i]

    def parts(self, i: int) -> frozenset[str]:
        found = self._parts.get(i)
        if found is None:
            found = self._parts[i] = table_parts_of(self.index.objects[i], self.index.scene)
        return found

    def pickable_unique(self) -> list[int]:
        return [i for i in self.index.unique if self.obj(i).pickupable]

    def pickable_groups(self, max_size: int | None = None) -> list[tuple[int, ...]]:
        return [g for g in self.index.groups if all(self.obj(i).pickupable for i in g)
                and (max_size is None or len(g) <= max_size)]

    def room(self, movers: list[int], part: str) -> bool:
        """Whether the objects ``movers``, put down one after another on ``part``, all find room there."""
        return room_on_part(self.index.scene, [self.obj(i) for i in movers], part, outlines=self.outlines)

    @_memo
    def by_weight(self, group: tuple[int, ...]) -> list[int] | None:
        """Group ids heaviest first, or ``None`` when two weights are closer than the margin."""
        ranked = sorted(group, key=lambda i: -self.obj(i).weight_gt)
        gaps = [self.obj(a).weight_gt - self.obj(b).weight_gt for a, b in zip(ranked, ranked[1:])]
        return ranked if self._close(gaps) and all(g >= self.weight_margin for g in gaps) else None

    def _close(self, gaps: list[float]) -> bool:
        """Whether enough of the compared pairs' ``gaps`` are within ``weight_gap_max`` (always, without one)."""
        if self.weight_gap_max is None:
            return True
        return sum(g <= self.weight_gap_max for g in gaps) >= self.weight_close_pairs

    def value(self, quantity: str, i: int):
        """The ground truth of ``quantity`` (``muble.programs.program.QUANTITIES``) of object ``i``, or None."""
        return QUANTITIES[quantity].truth(self.obj(i))

    def _apart(self, quantity: str, high: float, low: float) -> bool:
        return QUANTITIES[quantity].apart(high, low)

    @_memo
    def _largest_first(self, quantity: str, group: tuple[int, ...]) -> tuple[list[int], dict] | None:
        """The group's ids, the largest ``quantity`` first, with their values; ``None`` when one is unknown."""
        values = {i: self.value(quantity, i) for i in group}
        if any(v is None for v in values.values()):
            return None
        return sorted(group, key=lambda i: -values[i]), values

    def by_quantity(self, quantity: str, group: tuple[int, ...]) -> list[int] | None:
        """Group ids, the largest ``quantity`` first, or ``None`` when one is unknown or two are within the
        quantity's margin."""
        found = self._largest_first(quantity, group)
        if found is None:
            return None
        ranked, values = found
        apart = all(self._apart(quantity, values[a], values[b]) for a, b in zip(ranked, ranked[1:]))
        return ranked if apart else None

    def quantity_extreme(self, quantity: str, group: tuple[int, ...], which: str) -> int | None:
        """The object of the group that ``which`` (a superlative of the quantity: the first picks the largest)
        names, ``None`` unless it stands apart from the next by the margin (or a value is unknown)."""
        found = self._largest_first(quantity, group) if len(group) >= 2 else None
        if found is None:
            return None
        ranked, values = found
        top, second = (ranked[0], ranked[1]) if which == QUANTITIES[quantity].superlatives[0] \
            else (ranked[-1], ranked[-2])
        low, high = sorted((values[top], values[second]))
        return top if self._apart(quantity, high, low) else None

    def having(self, quantity: str, group: tuple[int, ...] | list[int], yes: bool = True) -> list[int] | None:
        """The members of the group that have the yes/no ``quantity`` (or, ``yes`` false, that do not), None
        when one of them carries no ground truth of it."""
        values = [self.value(quantity, i) for i in group]
        if any(v is None for v in values):
            return None
        return [i for i, v in zip(group, values) if bool(v) == yes]

    @_memo
    def extreme(self, group: tuple[int, ...], which: str) -> int | None:
        """The heaviest or lightest (``which``) of the group, ``None`` unless it stands apart from the next by the
        margin (and, with ``weight_gap_max``, enough other members lie within that of it: ``_close``)."""
        ranked = sorted(group, key=lambda i: -self.obj(i).weight_gt)
        top, second = (ranked[0], ranked[1]) if which == "heaviest" else (ranked[-1], ranked[-2])
        if abs(self.obj(top).weight_gt - self.obj(second).weight_gt) < self.weight_margin:
            return None
        if not self._close([abs(self.obj(top).weight_gt - self.obj(i).weight_gt) for i in group if i != top]):
            return None
        return top


def load_templates(path: str | Path) -> dict[str, Template]:
    """The templates of a template file (``muble_plugins.tasks.template_data``), by template id."""
    out = {}
    for spec in read_template_file(path):
        data = DataTemplate(spec)
        out[spec.template_id] = Template(spec.template_id, spec.task_id, spec.index, spec.texts, data.options,
                                         spec.description, data.feasible if data.dear else None, data.build,
                                         data.fill, tuple(str(step.get("type", "")) for step in spec.program))
    return out


BUILTIN_FILE = Path(__file__).with_name("shopvrb2_templates.yaml")
TEMPLATES: dict[str, Template] = load_templates(BUILTIN_FILE)  # the SHOP-VRB2 ten: the default mix
STIFFNESS_FILE = Path(__file__).with_name("stiffness_templates.yaml")
STIFFNESS_TEMPLATES: dict[str, Template] = load_templates(STIFFNESS_FILE)  # chosen by name only
PHYSICAL_FILE = Path(__file__).with_name("physical_templates.yaml")
PHYSICAL_TEMPLATES: dict[str, Template] = load_templates(PHYSICAL_FILE)  # chosen by name only
ALL_TEMPLATES: dict[str, Template] = {**TEMPLATES, **STIFFNESS_TEMPLATES, **PHYSICAL_TEMPLATES}

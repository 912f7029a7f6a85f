"""The books an agent keeps on what it observed, and how it retries a failed primitive: the oracle
(``muble_plugins.agents.oracle``) and the learned planner (``muble_plugins.learned``) keep them alike.

A sensor may err (``noise=wrist_ft``): an agent may then keep every reading of a property (``Readings``) and use
their mean, and decide a comparison between two objects only once their means differ by more than the readings'
scatter allows (``Certainty``); until then it measures again.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Callable, Mapping

from muble import ActionCall, ActionResult, PluginError, PrimitiveAction, SceneGraph, get_registry
from muble.core.observation import MEASURED_EXTRA, plain_measurement
from muble.core.symbolic import ArmState

from muble_plugins.common.symbolic import APPROACH, MOVE


Reading = bool | float | list[float]  # one measurement as plain Python (``plain_measurement``)
Known = dict[str, dict[int, Reading]]  # property (``PrimitiveAction.measures``) -> object id -> measured value
# property -> object id -> every reading made of it, in order (all of one kind: yes/no, numbers or lists)
Readings = dict[str, dict[int, list]]


def mean_reading(readings: list) -> Reading:
    """The value an agent uses of several readings of one property: their mean (of each coordinate, for a list
    such as [x, y] mm), the most frequent of yes/no readings (the latest on a tie); one reading as it is."""
    if len(readings) == 1:
        return readings[0]
    if isinstance(readings[0], bool):
        counts = Counter(readings)
        return readings[-1] if counts[True] == counts[False] else counts[True] > counts[False]
    if isinstance(readings[0], list):
        return [math.fsum(r[k] for r in readings) / len(readings) for k in range(len(readings[0]))]
    return math.fsum(readings) / len(readings)


def book(known: Known, last: ActionCall | None, result: ActionResult | None, held: int | None,
         readings: Readings | None = None) -> None:
    """Book the measurement a successful measuring primitive (``last``) made of the ``held`` object. With
    ``readings``, every reading is kept there and ``known`` holds their mean; without, the latest replaces the
    one before."""
    if last is None or result is None or not result.success or held is None or result.measurement is None:
        return
    prop = get_registry().measures(last.name)
    if prop is None:
        return
    value = plain_measurement(result.measurement)
    if readings is not None:
        kept = readings.setdefault(prop, {}).setdefault(held, [])
        kept.append(value)
        value = mean_reading(kept)
    known.setdefault(prop, {})[held] = value


def fill_known(scene: SceneGraph, known: Known, last: ActionCall | None, result: ActionResult | None,
               readings: Readings | None = None) -> None:
    """Fill an agent's copy of the observed ``scene`` with what it knows: the weights and other properties it
    measured (``known``), and the gripper's hover state. After a failed primitive (``result`` of ``last``) the hover
    and grasp-pose flags are cleared, so the plan starts over from hovering (a failed grasp or put-down leaves the
    hand where it should not stay); a world that reports no hover flags has them filled in from the last primitive.
    The oracle and the learned planner keep the same books, so the planner's labels fit.

    The scene shows the latest reading of what was measured; where ``readings`` holds several of an object, their
    mean (``known``) takes its place."""
    weights = known.get("weight", {})

    def several(name: str, obj_id: int) -> bool:
        return readings is not None and len(readings.get(name, {}).get(obj_id, ())) > 1

    for o in scene.objects:
        if o.id in weights and (o.weight is None or several("weight", o.id)):
            weight = weights[o.id]
            if isinstance(weight, (bool, list)):
                raise TypeError(f"the weight reading of object {o.id} is {weight!r}, not a number of grams")
            o.weight = weight
        for name, key in MEASURED_EXTRA.items():
            if o.id in known.get(name, {}) and (key not in o.extra or several(name, o.id)):
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
    factory = registry.get("primitive", name).record.factory
    if not (isinstance(factory, type) and issubclass(factory, PrimitiveAction)):
        raise PluginError(f"primitive {name!r} is registered with {factory!r}, not a PrimitiveAction class: it "
                          "declares no parameters")
    return {p.name for p in specs(factory.params)}


# Key of ``SceneGraph.extra`` under which an agent's own copy of the observed scene carries its ``Certainty`` for the
# task planner (``muble_plugins.common.task_planner.plan_next``); an observed scene never has it.
CERTAINTY = "certainty"


@dataclass(frozen=True)
class Certainty:
    """When an agent counts a comparison of two measured values as decided, from its books.

    One reading of a property errs with the standard deviation ``noise[property]`` (what the sensor's datasheet
    implies; a property not named, or 0, is read exactly). The mean of n readings then errs by noise/√n, and the
    difference of two objects' means by noise·√(1/n_a + 1/n_b): the comparison is decided when the means differ by
    more than ``sigmas`` times that. Until then the object read fewer times (the less certain) is measured again,
    up to ``max_readings`` readings of each, ``max_total`` in all, and while the episode's step budget spares a
    primitive for it (``spare_steps``); beyond that the means decide. A budget too short to decide every undecided
    pair is shared out: no object of them is read beyond the mean of their readings and the spare primitives (one
    close pair read to its bound would leave the next with a reading each). ``readings`` are the agent's books
    (kept up to date by ``book``). ``read_since_approach`` is the object measured since the hand last approached
    one, if any: approaching tares the wrist sensor, so a reading of that object now would share the last one's tare
    and its error."""

    noise: Mapping[str, float]
    readings: Readings
    sigmas: float = 2.5
    max_readings: int = 3
    read_since_approach: int | None = None
    # Readings of one property in the episode at most, all objects together (None: no bound): each is a primitive,
    # and an episode has a step budget; beyond it the means decide.
    max_total: int | None = None
    # The primitives the episode can still spend on measuring again (None: no bound): what its step budget leaves
    # after the rest of the plan, were every comparison decided now. Asked only of an undecided comparison; at 0 or
    # less the means decide.
    spare_steps: Callable[[], int] | None = None

    def measure_again(self, prop: str, pairs: list[tuple[int, int]]) -> tuple[int, ...]:
        """The objects to measure again before the order of ``pairs`` (object ids) by ``prop`` counts: those of the
        first undecided pair with the fewest readings (both on a tie) that may still be read again; empty when every
        pair is decided (a ``muble.programs.program.Recheck``).

        The object just measured (``read_since_approach``, still in the hand) is measured again first, while it has
        fewer readings than one of its undecided pairs needs (``readings_needed``) or than the other object of
        that pair: measuring it again costs one primitive where the property has one for that
        (``Property.again``), fetching another object several."""
        sd = float(self.noise.get(prop, 0.0) or 0.0)
        if not sd > 0:
            return ()
        books = self.readings.get(prop, {})
        if self.max_total is not None and sum(len(kept) for kept in books.values()) >= self.max_total:
            return ()
        pending: list[tuple[int, int, float]] = []  # the undecided pairs (object ids) with their means' gap
        for a, b in pairs:
            first, second = books.get(a, ()), books.get(b, ())
            if not (first and second and _numbers(first) and _numbers(second)):
                continue  # not this agent's readings (or not numbers): nothing to weigh them against
            gap = abs(math.fsum(first) / len(first) - math.fsum(second) / len(second))
            if gap <= self.sigmas * sd * math.sqrt(1.0 / len(first) + 1.0 / len(second)):
                pending.append((a, b, gap))
        counts = {obj_id: len(books[obj_id]) for a, b, _ in pending for obj_id in (a, b)
                  if len(books[obj_id]) < self.max_readings}
        if not counts:
            return ()
        share = math.inf  # readings of an object at most, for now: the budget's spare shared by the open objects
        if self.spare_steps is not None:
            spare = self.spare_steps()
            if spare <= 0:
                return ()
            share = (sum(counts.values()) + spare) / len(counts)
        held = self.read_since_approach
        undecided: list[dict[int, int]] = []  # per undecided pair, its objects that may be read again -> readings
        for a, b, gap in pending:
            open_ = {obj_id: counts[obj_id] for obj_id in (a, b) if obj_id in counts and counts[obj_id] < share}
            if held in open_:
                other = len(books[b]) if held == a else len(books[a])
                if open_[held] < max(other, min(self.readings_needed(sd, gap), share)):
                    return (held,)  # in the hand: one primitive more, where fetching the other takes several
            if open_:
                undecided.append(open_)
        if undecided:
            fewest = min(undecided[0].values())
            return tuple(obj_id for obj_id, n in undecided[0].items() if n == fewest)
        return ()

    def readings_needed(self, sd: float, gap: float) -> int:
        """Readings of each of two objects whose means ``gap`` apart would stand ``sigmas`` standard errors of their
        difference apart, for readings that err by ``sd``: 2·(sigmas·sd/gap)², at most ``max_readings``."""
        if gap <= 0.0:
            return self.max_readings
        return min(self.max_readings, max(1, math.ceil(2.0 * (self.sigmas * sd / gap) ** 2)))


def _numbers(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)

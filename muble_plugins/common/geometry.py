"""Table geometry the tasks need: room on a table part, resting-on and upright tests (object sizes, footprints and
the symbolic world's free spot: ``muble.stage.footprint``; the limits: ``muble.stage.rest``)."""
from __future__ import annotations

import math

import numpy as np

from muble import SceneGraph, SceneObject
from muble.core.observation import TOUCHING_TABLE
from muble.programs.program import table_parts_of
from muble.stage import rest
from muble.stage.footprint import Outlines, footprint_radius
from muble.stage.free_place import Shape, first_free_place, has_free_place
from muble.stage.geometry import tilt_deg
from muble.stage.table import BELOW_TABLE, scene_part_region

# How much higher than its base a stacked object's origin (its bottom) stands at least where the world records
# no contacts: a plate or tray holds what is put on it only its bottom's thickness (a few mm) above the table,
# while an object beside the base stands level with it. A plate's floor can be thinner than this (the original
# release's plate2 at import scale 0.6: 1.8 mm), so where contacts are recorded an object that touches its base
# and not the table is held up by the base at any height (``rests_on``).
RAISED_BY_BASE = 0.002
# Judging the end state (docs/tasks.md): a put-down object counts only when it rests upright (the limits:
# ``muble.stage.rest``).
# Room on a table part for an object to be put there: the free-place rule the placing primitives follow
# (``muble.stage.free_place``), with the outlines of the scene's bboxes for footprints (centred on the object's
# origin, so a mug's handle side may reach a little past them) and a wider gap than theirs (15 mm).
ROOM_GAP = 0.02
ROOM_SPACING = 0.01


def room_on_part(scene: SceneGraph, movers: list[SceneObject], part: str, gap: float = ROOM_GAP,
                 spacing: float = ROOM_SPACING, outlines: Outlines | None = None) -> bool:
    """Whether ``movers``, put down one after another on ``part`` (each at the free place nearest the part's
    centre, as the placing primitives choose), all find room beside the objects that stay and those placed
    before: the free-place rule of ``muble.stage.free_place`` on the outlines of the scene's bboxes
    (``muble.stage.footprint.outline``), ``gap`` apart, on a ``spacing`` grid. ``outlines``: the scene's outline
    memo, for a caller that asks about one scene many times.

    Only the places of the movers put down before another one matter (``first_free_place``); for the last, any
    place will do (``has_free_place``), which most often needs no outline built at all."""
    (x0, x1), (y0, y1) = scene_part_region(scene, part)
    footprints = outlines if outlines is not None else Outlines()
    moving = {o.id for o in movers}
    obstacles: list[Shape] = [footprints(o) for o in scene.objects if o.id not in moving]
    for n, obj in enumerate(movers):
        # outline - position, point by point (subtracting is adding the negation, to the bit)
        held = footprints(obj).shifted(-np.asarray(obj.position[:2], dtype=float))
        if n == len(movers) - 1:
            return has_free_place((x0, y0), (x1, y1), held, obstacles, gap=gap, spacing=spacing)
        place = first_free_place((x0, y0), (x1, y1), held, obstacles, gap=gap, spacing=spacing)
        if place is None:
            return False
        obstacles.append(held.shifted(place))
    return True


def tilt(obj: SceneObject) -> float:
    """Degrees between the object's z axis and the vertical (the world's record, else from its quaternion)."""
    if "tilt_deg" in obj.extra:
        return float(obj.extra["tilt_deg"])
    return tilt_deg(obj.orientation)


def upright(obj: SceneObject) -> bool:
    """``obj`` stands upright (its recorded tilt, ``muble.stage.rest.upright``)."""
    return rest.upright(tilt(obj))


def resting(obj: SceneObject) -> bool:
    """Not held and not moving (a world that records no speed counts as still)."""
    return not obj.extra.get("in_hand") and rest.at_rest(float(obj.extra.get("speed", 0.0)))


def touches(obj: SceneObject, support: int | str) -> bool:
    """``obj`` is in contact with ``support`` (an object id or ``"table"``); a world that records no contacts
    (a symbolic one, before the object was moved) is taken at its positions."""
    return "touching" not in obj.extra or support in obj.extra["touching"]


def clear_of_table(obj: SceneObject) -> bool:
    """The world records ``obj``'s contacts and the table is not among them."""
    return "touching" in obj.extra and TOUCHING_TABLE not in obj.extra["touching"]


def rests_on(top: SceneObject, base: SceneObject) -> bool:
    """``top`` stands on (or in) ``base``: resting, in contact with it, upright (both within ``UPRIGHT_DEG``),
    centred over its footprint, and held up by it: clear of the table, or standing ``RAISED_BY_BASE`` higher."""
    if not (resting(top) and touches(top, base.id) and upright(top) and upright(base)):
        return False
    dxy = math.hypot(top.position[0] - base.position[0], top.position[1] - base.position[1])
    if dxy > max(0.6 * footprint_radius(base), 0.03):
        return False
    return clear_of_table(top) or top.position[2] > base.position[2] + RAISED_BY_BASE


def on_table_part(obj: SceneObject, part: str, scene: SceneGraph) -> bool:
    """``obj`` rests upright on the table top itself, in ``part``."""
    return resting(obj) and touches(obj, TOUCHING_TABLE) and upright(obj) and part in table_parts_of(obj, scene)


def broken(scene: SceneGraph) -> list[int]:
    """Ids of objects that left the world: non-finite pose or fallen below the table top."""
    return [o.id for o in scene.objects
            if not np.all(np.isfinite(o.position)) or o.position[2] < -BELOW_TABLE]

"""Objects' sizes as a scene graph gives them (bbox extents), their footprints on the table, and the symbolic
world's free spot.

A scene object's ``bbox`` is its bounding box in its own frame: the full extents {x, y, z} along its own axes,
centred on its origin (the centre of its base) across and rising from it, or the eight corners of that box.
Where the box lies in the world follows from the object's pose: ``muble.stage.geometry.world_extents`` gives the
world-axis-aligned box that holds it, ``outline`` its footprint on the table.

No physics reads these: they serve worlds and checks that know objects only by their scene-graph records (the
symbolic world's ``move`` and ``lower``, the tasks' success checks and room checks). Where the symbolic world
puts an object down is the physical world's rule (``muble.stage.free_place``) applied to footprints of the boxes
(``free_spot``).
"""
from __future__ import annotations

import numpy as np

from muble.core.scene import SceneGraph, SceneObject
from muble.stage.free_place import Footprint, free_places
from muble.stage.geometry import hull_2d, quat_matrix, world_extents
from muble.stage.table import scene_part_region

# Sizes (m) assumed for an object whose record has no bbox.
DEFAULT_RADIUS = 0.04
DEFAULT_HEIGHT = 0.06
# The corners of a unit box centred on the origin across and rising from it (an object's bbox about its origin).
_UNIT_BOX = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (0.0, 1.0)])


def extents(obj: SceneObject) -> tuple[float, float, float]:
    """Full size along the object's own x, y, z from the bbox (extents dict or eight corners), or defaults."""
    box = obj.bbox
    if isinstance(box, dict):
        return float(box["x"]), float(box["y"]), float(box["z"])
    if isinstance(box, list) and len(box) == 8:
        pts = np.asarray(box, dtype=float)
        span = pts.max(axis=0) - pts.min(axis=0)
        return float(span[0]), float(span[1]), float(span[2])
    return 2 * DEFAULT_RADIUS, 2 * DEFAULT_RADIUS, DEFAULT_HEIGHT


def footprint_radius(obj: SceneObject) -> float:
    """Half the larger horizontal extent of ``obj``'s bounding box (metres): the radius it needs on the table."""
    ex, ey, _ = extents(obj)
    return 0.5 * max(ex, ey)


def height(obj: SceneObject) -> float:
    """How tall ``obj`` stands (metres): the vertical extent of its bounding box as it is turned."""
    return float(world_extents(extents(obj), obj.orientation)[2])


def outline(obj: SceneObject) -> np.ndarray:
    """The footprint of ``obj``'s bounding box on the table plane as the object stands (its pose): the convex
    hull, counter-clockwise, of the box's corners seen from above."""
    return _outline(_corners(extents(obj), obj.orientation), np.asarray(obj.position[:2], dtype=float))


def _corners(size: tuple[float, float, float], quat) -> np.ndarray:
    """The eight corners of a box of extents ``size`` about its origin (``_UNIT_BOX``), turned by ``quat``."""
    return (_UNIT_BOX * size) @ quat_matrix(quat).T


def _outline(corners: np.ndarray, position: np.ndarray) -> np.ndarray:
    return hull_2d(corners[:, :2]) + position


class Outlines:
    """The ``outline``s of a scene's objects as ``Footprint``s, each built at most once: for checks that ask for
    the same footprints many times (the tasks' room check asks for every object's on each option it tries). A
    footprint knows its box's corners at once and builds the outline (a convex hull) only when a search needs it.

    An entry is keyed by the object's id together with everything its outline is computed from (its extents,
    orientation and position on the table), so an object that was moved, turned or resized, or another scene's
    object under the same id, gets a new footprint and is never answered from a stale one. The outlines built
    are read-only: they are shared between calls."""

    def __init__(self) -> None:
        self._known: dict[tuple, Footprint] = {}

    def __call__(self, obj: SceneObject) -> Footprint:
        size = extents(obj)
        # Bytes, not numbers: -0.0 and 0.0 (equal as keys) give outlines whose zeros differ in sign.
        key = (obj.id, np.array(size).tobytes(), np.asarray(obj.orientation, dtype=float).tobytes(),
               np.asarray(obj.position[:2], dtype=float).tobytes())
        found = self._known.get(key)
        if found is None:
            corners = _corners(size, obj.orientation)
            position = np.asarray(obj.position[:2], dtype=float)

            def build() -> np.ndarray:
                shape = _outline(corners, position)
                shape.flags.writeable = False
                return shape

            found = self._known[key] = Footprint(corners[:, :2] + position, build)
        return found


def axis_outline(obj: SceneObject) -> np.ndarray:
    """The rectangle, counter-clockwise, of ``obj``'s bounding box's horizontal extents laid along the world axes
    about its position, whatever its turn: the footprint the symbolic world puts objects down by (``free_spot``).
    For a round object (equal x and y extents) it holds the object at any turn."""
    ex, ey, _ = extents(obj)
    corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * [ex, ey]
    return corners + np.asarray(obj.position[:2], dtype=float)


def free_spot(scene: SceneGraph, obj: SceneObject, part: str) -> list[float] | None:
    """Where ``obj`` is put down on ``part``: the first free place of the one free-place rule
    (``muble.stage.free_place``, nearest the part's centre) with ``axis_outline`` footprints; None when the part
    has no room for it. The scene generator keeps an instruction only when the symbolic world completes its
    ground truth, so its files depend on these answers (a protocol's recorded data hashes with them)."""
    (x0, x1), (y0, y1) = scene_part_region(scene, part)
    held = axis_outline(obj) - np.asarray(obj.position[:2], dtype=float)
    others = [axis_outline(other) for other in scene.objects if other.id != obj.id]
    places = free_places((x0, y0), (x1, y1), held, others)
    if not places:
        return None
    return [round(float(places[0][0]), 4), round(float(places[0][1]), 4), 0.0]

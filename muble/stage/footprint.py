"""Objects' sizes on the table as a scene graph gives them (bbox extents), and the symbolic world's free spot.

No physics reads these: they serve worlds and checks that know objects only by their scene-graph records (the
symbolic world's ``move`` and ``lower``, the tasks' success checks). Where the symbolic world puts an object down
is the physical world's rule (``muble.stage.free_place``) applied to bounding boxes.
"""
from __future__ import annotations

import numpy as np

from muble.core.scene import SceneGraph, SceneObject
from muble.stage.free_place import free_places
from muble.stage.table import part_region, scene_top

# Sizes (m) assumed for an object whose record has no bbox.
DEFAULT_RADIUS = 0.04
DEFAULT_HEIGHT = 0.06


def extents(obj: SceneObject) -> tuple[float, float, float]:
    """Full size along x, y, z from the bbox (extents dict or eight corners), or defaults."""
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
    """The vertical extent of ``obj``'s bounding box (metres)."""
    return extents(obj)[2]


def outline(obj: SceneObject) -> np.ndarray:
    """The corners, on the table plane, of ``obj``'s bounding box about its position (scene graphs keep world
    axis-aligned boxes)."""
    ex, ey, _ = extents(obj)
    corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * [ex, ey]
    return corners + np.asarray(obj.position[:2], dtype=float)


def free_spot(scene: SceneGraph, obj: SceneObject, part: str) -> list[float] | None:
    """Where ``obj`` is put down on ``part``: the first free place of the one free-place rule
    (``muble.stage.free_place``, nearest the part's centre) with bounding boxes as footprints; None when the part
    has no room for it."""
    (x0, x1), (y0, y1) = part_region(part, scene_top(scene))
    held = outline(obj) - np.asarray(obj.position[:2], dtype=float)
    others = [outline(other) for other in scene.objects if other.id != obj.id]
    places = free_places((x0, y0), (x1, y1), held, others)
    if not places:
        return None
    return [round(float(places[0][0]), 4), round(float(places[0][1]), 4), 0.0]

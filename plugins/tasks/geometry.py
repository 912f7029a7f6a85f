"""Table geometry the tasks need: object footprints and heights, free spots in a table part, resting-on tests."""
from __future__ import annotations

import math

import numpy as np

from muble import SceneGraph, SceneObject
from muble.core.program import table_parts_of
from muble.core.table import part_region

# Where SHOP-VRB2 scenes stand objects (world x, y in metres; synthetic scenes sample it). The table parts and
# where the robot places objects are defined in muble.core.table.
TABLE_REGION = ((0.30, 0.72), (-0.34, 0.12))
DEFAULT_RADIUS = 0.04
DEFAULT_HEIGHT = 0.06
# How much higher than its base a stacked object's origin (its bottom) stands at least: a plate or tray holds
# what is put on it only its bottom's thickness (a few mm) above the table, while an object beside the base
# stands level with it.
RAISED_BY_BASE = 0.002
BROKEN_BELOW_Z = -0.05  # an object this far below the table top has fallen off


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
    ex, ey, _ = extents(obj)
    return 0.5 * max(ex, ey)


def height(obj: SceneObject) -> float:
    return extents(obj)[2]


def free_spot(scene: SceneGraph, obj: SceneObject, part: str, step: float = 0.02) -> list[float]:
    """The point of ``part`` with the most clearance from every other object (deterministic)."""
    (x0, x1), (y0, y1) = part_region(part)
    r = footprint_radius(obj)
    xs = np.arange(x0 + r, x1 - r + 1e-9, step) if x1 - x0 > 2 * r else np.array([(x0 + x1) / 2])
    ys = np.arange(y0 + r, y1 - r + 1e-9, step) if y1 - y0 > 2 * r else np.array([(y0 + y1) / 2])
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    clearance = np.full(gx.shape, np.inf)
    for other in scene.objects:
        if other.id == obj.id:
            continue
        d = np.hypot(gx - other.position[0], gy - other.position[1]) - footprint_radius(other) - r
        clearance = np.minimum(clearance, d)
    best = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    return [round(float(gx[best]), 4), round(float(gy[best]), 4), 0.0]


def rests_on(top: SceneObject, base: SceneObject) -> bool:
    """``top`` stands on (or in) ``base``: centred over its footprint and higher, not held."""
    if top.extra.get("in_hand"):
        return False
    dxy = math.hypot(top.position[0] - base.position[0], top.position[1] - base.position[1])
    return dxy <= max(0.6 * footprint_radius(base), 0.03) and top.position[2] > base.position[2] + RAISED_BY_BASE


def on_table_part(obj: SceneObject, part: str, scene: SceneGraph) -> bool:
    return not obj.extra.get("in_hand") and part in table_parts_of(obj, scene)


def broken(scene: SceneGraph) -> list[int]:
    """Ids of objects that left the world: non-finite pose or fallen below the table top."""
    return [o.id for o in scene.objects
            if not np.all(np.isfinite(o.position)) or o.position[2] < BROKEN_BELOW_Z]

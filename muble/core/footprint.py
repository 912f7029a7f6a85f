"""Objects' sizes on the table as a scene graph gives them (bbox extents), and the symbolic world's free spot.

No physics reads these: they serve worlds and checks that know objects only by their scene-graph records (the
symbolic world's ``move`` and ``lower``, the tasks' success checks).
"""
from __future__ import annotations

import numpy as np

from muble.core.scene import SceneGraph, SceneObject
from muble.core.table import part_region

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

"""Table geometry the tasks need: room on a table part, resting-on and upright tests (object sizes and the
symbolic world's free spot: ``muble.stage.footprint``)."""
from __future__ import annotations

import functools
import math

import numpy as np

from muble import SceneGraph, SceneObject
from muble.core.observation import TOUCHING_TABLE
from muble.programs.program import table_parts_of
from muble.stage.footprint import extents, footprint_radius
from muble.stage.geometry import tilt_deg
from muble.stage.rest import UPRIGHT_DEG, at_rest
from muble.stage.table import BELOW_TABLE, part_region, scene_top

# Where SHOP-VRB2 scenes stand objects (world x, y in metres; synthetic scenes sample it). The table parts and
# where the robot places objects are defined in muble.stage.table.
TABLE_REGION = ((0.30, 0.72), (-0.34, 0.12))
# How much higher than its base a stacked object's origin (its bottom) stands at least where the world records
# no contacts: a plate or tray holds what is put on it only its bottom's thickness (a few mm) above the table,
# while an object beside the base stands level with it. A plate's floor can be thinner than this (the original
# release's plate2 at import scale 0.6: 1.8 mm), so where contacts are recorded an object that touches its base
# and not the table is held up by the base at any height (``rests_on``).
RAISED_BY_BASE = 0.002
# Judging the end state (docs/tasks.md): a put-down object counts only when it rests upright (the limits:
# ``muble.stage.rest``).
# Room on a table part for an object to be put there: the placing primitives keep 15 mm between real footprints
# on a 1 cm grid; here bboxes (centred on the object's origin, so a mug's handle side may reach a little past
# them) stand in for footprints, with a wider gap.
ROOM_GAP = 0.02
ROOM_SPACING = 0.01
ROOM_BATCH = 96  # candidate centres tested at once


def _box(obj: SceneObject) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre x, y; object x and y axes as world columns; half sizes) of the object's bbox seen from above."""
    ex, ey, _ = extents(obj)
    w, z = float(obj.orientation[0]), float(obj.orientation[3])
    yaw = 2.0 * math.atan2(z, w) if abs(w) + abs(z) > 1e-9 else 0.0
    c, s = math.cos(yaw), math.sin(yaw)
    return np.asarray(obj.position[:2], dtype=float), np.array([[c, -s], [s, c]]), np.array([ex / 2, ey / 2])


def _separating_axes(mover, obstacles: list, gap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the separating-axis test of ``mover``'s box (turned as it stands) against each obstacle box: the four
    axes of every pair as columns (2, 4n), each obstacle centre's projection on them, and the distance below
    which the two boxes come closer than ``gap`` along each."""
    _, rot_a, half_a = mover
    axes, centres, reach = [], [], []
    for centre_b, rot_b, half_b in obstacles:
        pair = np.hstack([rot_a, rot_b])
        axes.append(pair)
        centres.append(centre_b @ pair)
        reach.append(np.abs(rot_a.T @ pair).T @ half_a + np.abs(rot_b.T @ pair).T @ half_b + gap)
    return np.hstack(axes), np.concatenate(centres), np.concatenate(reach)


@functools.lru_cache(maxsize=None)
def _grid(part: str, spacing: float, top) -> tuple[np.ndarray, tuple[tuple[float, float], tuple[float, float]]]:
    """The part's candidate centres on a ``spacing`` grid, nearest its middle first, and its ranges (kept inside the
    table top ``top``, see ``muble.stage.table.part_region``)."""
    (x0, x1), (y0, y1) = region = part_region(part, top)
    gx, gy = np.meshgrid(np.arange(x0, x1 + 1e-9, spacing), np.arange(y0, y1 + 1e-9, spacing), indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)
    middle = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    points = points[np.argsort(np.linalg.norm(points - middle, axis=1), kind="stable")]
    points.setflags(write=False)
    return points, region


def room_on_part(scene: SceneGraph, movers: list[SceneObject], part: str, gap: float = ROOM_GAP,
                 spacing: float = ROOM_SPACING) -> bool:
    """Whether ``movers``, put down one after another on ``part`` (each at the free centre nearest the part's
    middle, as the placing primitives choose), all find room beside the objects that stay and those placed
    before. Boxes from the scene's bboxes, turned as the objects stand, stand in for their footprints."""
    points, ((x0, x1), (y0, y1)) = _grid(part, spacing, scene_top(scene))
    moving = {o.id for o in movers}
    obstacles = [_box(o) for o in scene.objects if o.id not in moving]
    for obj in movers:
        box = _box(obj)
        # Only what can come within reach of a centre in the part matters (bounding circles against its ranges).
        reach = float(np.linalg.norm(box[2])) + gap
        near = [b for b in obstacles
                if math.hypot(max(x0 - b[0][0], 0.0, b[0][0] - x1), max(y0 - b[0][1], 0.0, b[0][1] - y1))
                < reach + float(np.linalg.norm(b[2]))]
        spot = points[0] if not near else None
        if near:
            axes, centres, reach = _separating_axes(box, near, gap)
            # Nearest the middle first, a batch at a time: a part with room usually has it in the first batch.
            # A centre is blocked by an obstacle when the boxes overlap (within the gap) along all four axes.
            for start in range(0, len(points), ROOM_BATCH):
                batch = points[start:start + ROOM_BATCH]
                close = np.abs(batch @ axes - centres) < reach
                free = ~close.reshape(len(batch), len(near), 4).all(axis=2).any(axis=1)
                if free.any():
                    spot = batch[int(np.argmax(free))]
                    break
        if spot is None:
            return False
        obstacles.append((spot, box[1], box[2]))
    return True


def tilt(obj: SceneObject) -> float:
    """Degrees between the object's z axis and the vertical (the world's record, else from its quaternion)."""
    if "tilt_deg" in obj.extra:
        return float(obj.extra["tilt_deg"])
    return tilt_deg(obj.orientation)


def upright(obj: SceneObject) -> bool:
    """``obj`` stands upright (its recorded tilt within ``muble.stage.rest.UPRIGHT_DEG``)."""
    return tilt(obj) <= UPRIGHT_DEG


def resting(obj: SceneObject) -> bool:
    """Not held and not moving (a world that records no speed counts as still)."""
    return not obj.extra.get("in_hand") and at_rest(float(obj.extra.get("speed", 0.0)))


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

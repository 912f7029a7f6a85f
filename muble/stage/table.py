"""The table's named parts: the one definition that task programs, placing primitives and success checks share.

Scene frame: the robot stands at the origin looking along +x over the table, the top is the plane z = 0. Parts
are named as seen from the scene camera, which looks at the robot from the far side: "left" is -y, "front" the
far half (+x), "back" the half by the robot. The split lines pass through ``TABLE_CENTRE`` (turned by the scene's
``directions`` when it has them); "centre" is a disc around it. Objects are placed within ``PLACE_REGION``, the
area the arm reaches over the table, and at least ``SPLIT_MARGIN`` from a split line, so a placed
object's part is never borderline.
"""
from __future__ import annotations

from typing import Mapping, Sequence

from muble.core.errors import PlanningError, unknown_name

# The table top in the scene frame for robosuite's standard table placement (0.9 x 1.2 m, its near edge 0.16 m in
# front of the robot's base axis), and the clearance every object keeps from that axis: the robot's pedestal
# (radius 0.18 m) stands 0.14 m above the table top.
TABLE_X = (0.16, 1.06)
TABLE_Y = (-0.6, 0.6)
ROBOT_CLEARANCE = 0.22
TABLE_CENTRE = (0.5, 0.0)  # x, y (m) where the split lines cross
TABLE_CENTRE_RADIUS = 0.08  # m; objects this close to the centre are also in "centre"
# x and y ranges (m) for the centre of an object the robot places: the generated scenes' area (x 0.28-0.72,
# y -0.36-0.12) widened to where a top-down hand still reaches comfortably, so that every part, "right"
# included, has room beside the objects already standing in it.
PLACE_REGION = ((0.28, 0.74), (-0.40, 0.26))
SPLIT_MARGIN = 0.04  # m between a placed object's centre and a split line
BELOW_TABLE = 0.05  # m: an object whose origin is this far below the table top has fallen off
TABLE_MARGIN = 0.08  # m kept free along the table top's edges when choosing a place on it
# The original MuBlE release's desk top (x, y size in m) and how far the robot's base stands in from its back edge;
# ``muble.sim.world``'s ``original`` stage is built from these.
DESK_SIZE = (1.36, 0.8)
DESK_BASE_INSET = 0.23
DESK_CENTRE_X = DESK_SIZE[0] / 2 - DESK_BASE_INSET
# The table top's (x0, x1), (y0, y1) in the scene frame on each stage a scene is built on (``muble.sim.world``'s
# ``STAGES`` builds them; a test checks the two agree), by the name a scene file's ``stage`` key gives. The part
# regions are kept ``TABLE_MARGIN`` inside the top, in both worlds: on robosuite's table that leaves them as
# ``PLACE_REGION`` has them, on the narrower desk it keeps placed objects off its left edge.
STAGE_TOPS = {
    "robosuite": (TABLE_X, TABLE_Y),
    "original": ((DESK_CENTRE_X - DESK_SIZE[0] / 2, DESK_CENTRE_X + DESK_SIZE[0] / 2),
                 (-DESK_SIZE[1] / 2, DESK_SIZE[1] / 2)),
}
UNNAMED_STAGE = "robosuite"  # the stage of a scene file that names none (protocol shopvrb2_v1's among them)
STAGE_KEY = "stage"  # the scene file's key naming its stage
TABLE_PARTS = ("left", "right", "front", "back", "centre")
OPPOSITE_PART = {"left": "right", "right": "left", "front": "back", "back": "front"}
_ALIASES = {"center": "centre"}


def canonical_part(part: str) -> str:
    """The part's name (``center`` is ``centre``); an unknown name raises ``PlanningError`` listing the valid ones."""
    name = _ALIASES.get(part, part)
    if name not in TABLE_PARTS:
        raise PlanningError(unknown_name("table part", str(part), TABLE_PARTS))
    return name


def parts_at(x: float, y: float, directions: Mapping[str, Sequence[float]] | None = None) -> frozenset[str]:
    """The parts a point of the table top lies in: one side of each split line, plus "centre" near the middle."""
    dx, dy = float(x) - TABLE_CENTRE[0], float(y) - TABLE_CENTRE[1]
    left_dir, front_dir = (0.0, -1.0), (1.0, 0.0)
    if directions:
        if "left" in directions:
            left_dir = tuple(directions["left"][:2])
        if "front" in directions:
            front_dir = tuple(directions["front"][:2])
    along_left = dx * left_dir[0] + dy * left_dir[1]
    along_front = dx * front_dir[0] + dy * front_dir[1]
    parts = {"left" if along_left > 0 else "right", "front" if along_front > 0 else "back"}
    if dx * dx + dy * dy <= TABLE_CENTRE_RADIUS ** 2:
        parts.add("centre")
    return frozenset(parts)


def stage_name(scene) -> str:
    """The name of the stage ``scene`` stands on: its file's ``stage`` key, else ``original`` for a scene of the
    original release's files (which name none; they were made on it), else ``UNNAMED_STAGE``."""
    return scene.extra.get(STAGE_KEY) or ("original" if scene.from_original_release else UNNAMED_STAGE)


def scene_top(scene) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The table top's ranges for ``scene``'s stage (None for a stage this module does not know: the part regions
    are then not clipped, and the physical world's own table still clips its own)."""
    return STAGE_TOPS.get(stage_name(scene))


def part_region(part: str, top: tuple[tuple[float, float], tuple[float, float]] | None = None,
                margin: float = TABLE_MARGIN) -> tuple[tuple[float, float], tuple[float, float]]:
    """The (x0, x1), (y0, y1) ranges where a placed object's centre may go to lie in ``part``; with ``top`` (the
    table top's (x0, x1), (y0, y1), see ``scene_top``) kept ``margin`` inside its edges."""
    part = canonical_part(part)
    (x0, x1), (y0, y1) = PLACE_REGION
    cx, cy = TABLE_CENTRE
    if part == "left":
        ranges = (x0, x1), (y0, cy - SPLIT_MARGIN)
    elif part == "right":
        ranges = (x0, x1), (cy + SPLIT_MARGIN, y1)
    elif part == "front":
        ranges = (cx + SPLIT_MARGIN, x1), (y0, y1)
    elif part == "back":
        ranges = (x0, cx - SPLIT_MARGIN), (y0, y1)
    else:
        # A square inside the centre disc, its corners SPLIT_MARGIN / 2 within the circle.
        half = (TABLE_CENTRE_RADIUS - SPLIT_MARGIN / 2) / 2 ** 0.5
        ranges = (cx - half, cx + half), (cy - half, cy + half)
    if top is None:
        return ranges
    return tuple((max(lo, edge_lo + margin), min(hi, edge_hi - margin))  # type: ignore[return-value]
                 for (lo, hi), (edge_lo, edge_hi) in zip(ranges, top))

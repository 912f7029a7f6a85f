"""The table and the stages it stands on: the one description of the tabletop that scene generation, task
programs, placing primitives, success checks and the simulation share.

Scene frame: the robot stands at the origin looking along +x over the table, the top is the plane z = 0. Parts
(``muble.core.types.TABLE_PARTS``) are named as seen from the scene camera, which looks at the robot from the far
side: "left" is -y, "front" the far half (+x), "back" the half by the robot. The split lines pass through
``TABLE_CENTRE`` (turned by the scene's ``directions`` when it has them); "centre" is a disc around it.

A ``Stage`` is where the table and the robot stand (``STAGES``, by the name a scene file's ``stage`` key gives):
how the simulation builds them, the table top, and on it the area generated scenes stand objects in, the area the
robot places them in and the clearances both keep. Every rectangle on the table is a stage's or derived from one:
a part's region (``Stage.part_region``) is the stage's place area split at the part's lines, ``SPLIT_MARGIN`` from
them so that a placed object's part is never borderline, and kept ``edge_margin`` inside the table top.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from muble.core.errors import ConfigError, unknown_name
from muble.core.types import canonical_part

if TYPE_CHECKING:  # pragma: no cover
    from muble.core.environment import Environment

Ranges = tuple[tuple[float, float], tuple[float, float]]
"""A rectangle on the table: its (x0, x1), (y0, y1) ranges in the scene frame, metres."""

TABLE_CENTRE = (0.5, 0.0)  # x, y (m) where the split lines cross
TABLE_CENTRE_RADIUS = 0.08  # m; objects this close to the centre are also in "centre"
SPLIT_MARGIN = 0.04  # m between a placed object's centre and a split line
BELOW_TABLE = 0.05  # m: an object whose origin is this far below the table top has fallen off
ROBOSUITE_NEAR_EDGE = 0.16  # m from the robot's base axis to the table's near edge, robosuite's placement (Panda)
OPPOSITE_PART = {"left": "right", "right": "left", "front": "back", "back": "front"}


@dataclass(frozen=True)
class Stage:
    """Where the table and the robot stand, and where objects go on the table.

    How ``muble.sim.world`` builds it: ``table_size`` is the table's full x/y/z size; ``table_centre_x`` puts its
    centre on the robot's axis (``None``: robosuite's placement for the robot, the table's near edge just in front
    of the robot's mount, ``ROBOSUITE_NEAR_EDGE`` for the Panda); ``mount`` keeps the robot's robosuite pedestal
    (``False``: the arm's base stands on the table top at the origin); ``gripper`` is the stage's default gripper
    (``None``: the robot's own; ``robot.gripper`` overrides either) and ``start_qpos`` the arm's rest configuration
    per robot (robots not named start at robosuite's).

    Where objects go, (x0, x1), (y0, y1) ranges in the scene frame: ``reach``, where the scene generator stands
    objects' base centres, the arm's reachable part of the table (the original release's scenes, seen by the same
    camera, place objects within x 0.30-0.70, y -0.33-0.10); ``place``, where the robot places an object's centre,
    split into the table's parts: the generated scenes' area widened to where a top-down hand still reaches
    comfortably, so that every part, "right" included, has room beside the objects already standing in it. The
    clearances: ``edge_margin`` is kept free along the table top's edges when choosing a place on it;
    ``robot_clearance`` between the robot's base axis and any generated object's footprint (robosuite's pedestal,
    radius 0.18 m, stands 0.14 m above the table top); ``object_margin`` between generated objects' meshes.
    """

    name: str
    table_size: tuple[float, float, float]
    table_centre_x: float | None = None
    mount: bool = True
    gripper: str | None = None
    start_qpos: dict[str, tuple[float, ...]] = field(default_factory=dict)
    reach: Ranges = ((0.28, 0.72), (-0.36, 0.12))
    place: Ranges = ((0.28, 0.74), (-0.40, 0.26))
    edge_margin: float = 0.08
    robot_clearance: float = 0.22
    object_margin: float = 0.01

    @property
    def top(self) -> Ranges:
        """The table top's (x0, x1), (y0, y1) in the scene frame (robosuite's placement: as for the Panda)."""
        hx, hy = self.table_size[0] / 2.0, self.table_size[1] / 2.0
        if self.table_centre_x is None:
            return (ROBOSUITE_NEAR_EDGE, ROBOSUITE_NEAR_EDGE + self.table_size[0]), (-hy, hy)
        return (self.table_centre_x - hx, self.table_centre_x + hx), (-hy, hy)

    def part_region(self, part: str, top: Ranges | None = None) -> Ranges:
        """The (x0, x1), (y0, y1) ranges where a placed object's centre may go to lie in ``part``: ``place`` split
        at the part's lines, kept ``edge_margin`` inside the table top (``top``; default: this stage's)."""
        return part_region(part, self.place, self.top if top is None else top, self.edge_margin)


STAGES = {
    # robosuite's table stage, on which every scene of protocol shopvrb2_v1 was generated: a 0.9 x 1.2 m table,
    # the robot on its pedestal behind the near edge.
    "robosuite": Stage("robosuite", (0.9, 1.2, 0.05)),
    # The original MuBlE release's stage (michaal94/MuBlE environment/tabletop_env.py): a 1.36 x 0.8 m desk top
    # 2.6 cm thick, the Panda standing on it without a mount, its base 0.23 m in from the back edge, a Robotiq 85
    # gripper, and the arm bent over the table towards the camera at rest. Its scene files were made on it. Its
    # part regions, kept ``edge_margin`` inside the narrower desk, keep placed objects off its left edge.
    "original": Stage("original", (1.36, 0.8, 0.026), table_centre_x=1.36 / 2 - 0.23, mount=False,
                      gripper="Robotiq85Gripper",
                      start_qpos={"Panda": (0.0, 0.0, 0.0, -0.75 * math.pi, 0.0, 0.75 * math.pi, 0.25 * math.pi)}),
}
# A scene file that names no stage stands on robosuite's, on which every scene was generated before stages could
# be chosen, protocol shopvrb2_v1's included. The generator writes the key (``STAGE_KEY``) for any other stage
# only, so a file made on robosuite's keeps its bytes whatever stage the generator defaults to.
UNNAMED_STAGE = "robosuite"
STAGE_KEY = "stage"  # the scene file's key naming its stage


def stage_named(name: str, where: str = "robot.stage") -> Stage:
    """The stage called ``name`` (given by ``where``); an unknown name raises ``ConfigError`` listing the stages."""
    if name not in STAGES:
        raise ConfigError(f"{unknown_name('stage', str(name), list(STAGES))} (from {where})")
    return STAGES[name]


def stage_name(scene) -> str:
    """The name of the stage ``scene`` stands on: its file's ``stage`` key, else ``original`` for a scene of the
    original release's files (which name none; they were made on it), else ``UNNAMED_STAGE``."""
    return scene.extra.get(STAGE_KEY) or ("original" if scene.from_original_release else UNNAMED_STAGE)


def stage_of(scene) -> Stage | None:
    """The stage ``scene`` stands on; None for a stage this module does not know."""
    return STAGES.get(stage_name(scene))


def parts_at(x: float, y: float, directions: Mapping[str, Sequence[float]] | None = None) -> frozenset[str]:
    """The parts a point of the table top lies in: one side of each split line, plus "centre" near the middle."""
    dx, dy = float(x) - TABLE_CENTRE[0], float(y) - TABLE_CENTRE[1]
    left_dir: tuple[float, ...] = (0.0, -1.0)
    front_dir: tuple[float, ...] = (1.0, 0.0)
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


def part_region(part: str, place: Ranges, top: Ranges | None = None, margin: float = 0.0) -> Ranges:
    """The (x0, x1), (y0, y1) ranges of ``place`` where a placed object's centre lies in ``part``, ``SPLIT_MARGIN``
    from its split lines; with ``top`` (the table top's ranges) kept ``margin`` inside its edges."""
    part = canonical_part(part)
    (x0, x1), (y0, y1) = place
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


def scene_part_region(scene, part: str) -> Ranges:
    """``part``'s region on the stage ``scene`` stands on (``Stage.part_region``); for a stage this module does not
    know, the region of the unnamed stage's place area, not clipped to a table top."""
    stage = stage_of(scene)
    if stage is None:
        return part_region(part, STAGES[UNNAMED_STAGE].place)
    return stage.part_region(part)


def part_box(env: "Environment", part: str) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) corners in x, y where a placed object's centre goes to lie in ``part`` of the physical world's
    table: the region of its stage (``env.names.stage``) kept inside the table top as the model has it
    (``env.table()``). An unknown part name raises ``PlanningError``."""
    table = env.table()
    lo, hi = table.centre - table.half, table.centre + table.half
    (x0, x1), (y0, y1) = stage_named(env.names.stage).part_region(part, ((lo[0], hi[0]), (lo[1], hi[1])))
    return np.array([x0, y0]), np.array([x1, y1])

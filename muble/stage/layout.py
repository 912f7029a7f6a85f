"""Where the objects of a new scene stand: the one layout sampler of the scene generator and the synthetic scenes.

Each object's pose is drawn uniformly in the stage's reach area (``muble.stage.table.Stage.reach``), at any turn
about the vertical, and kept when its whole footprint lies on the table top, at least ``robot_clearance`` from the
robot's base axis, and ``margin`` or more from every object placed before. A shape brings its footprint (the
convex hull seen from above, in its own frame), its radius about its base centre and itself placed (``posed``),
which the layout's ``distance`` measures: the generator's objects are their meshes, placed for python-fcl's exact
distance (``muble.generation.placement``); the synthetic scenes' are their bounding boxes (``BoxShape``), whose
outlines on the table plane are measured in the plane.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Protocol

import numpy as np

from muble.stage.geometry import polygon_distance, yaw_matrix, yaw_quat
from muble.stage.table import Stage


@dataclass
class Placement:
    """An object resting on the table: base centre at (x, y, 0), turned by ``yaw`` radians."""

    x: float
    y: float
    yaw: float

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, 0.0])

    @property
    def quat(self) -> np.ndarray:
        return yaw_quat(self.yaw)

    def transform(self, vertices: np.ndarray) -> np.ndarray:
        return vertices @ yaw_matrix(self.yaw).T + self.position


class Shape(Protocol):
    """What the layout needs of an object: ``footprint``, the convex hull (n x 2, counter-clockwise) of what it
    covers of the table seen from above in its own frame; ``radius``, the farthest the object reaches from its
    base centre's vertical axis (m); and the object placed, as the layout's ``distance`` takes it."""

    footprint: np.ndarray
    radius: float

    def posed(self, placement: Placement) -> Any: ...


def footprint_at(footprint: np.ndarray, placement: Placement) -> np.ndarray:
    """The footprint hull (object frame) on the table at ``placement`` (world x, y)."""
    c, s = math.cos(placement.yaw), math.sin(placement.yaw)
    fx, fy = footprint[:, 0], footprint[:, 1]
    return np.stack([fx * c - fy * s + placement.x, fx * s + fy * c + placement.y], axis=1)


def fits(footprint: np.ndarray, placement: Placement, x_range, y_range) -> bool:
    """Whether the whole footprint at ``placement`` lies within ``x_range`` x ``y_range``."""
    hull = footprint_at(footprint, placement)
    x, y = hull[:, 0], hull[:, 1]
    return bool(x.min() >= x_range[0] and x.max() <= x_range[1] and y.min() >= y_range[0]
                and y.max() <= y_range[1])


def distance_to_point(footprint: np.ndarray, placement: Placement, point_xy) -> float:
    """Least distance (m) from the footprint at ``placement`` to a point of the table plane (0 if inside)."""
    hull = footprint_at(footprint, placement)
    a, b = hull, np.roll(hull, -1, axis=0)
    ab, ap = b - a, np.asarray(point_xy, dtype=float) - a
    t = np.clip(np.einsum("ij,ij->i", ap, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18), 0.0, 1.0)
    gap = float(np.linalg.norm(ap - t[:, None] * ab, axis=1).min())
    # Inside a counter-clockwise convex hull the point is left of every edge.
    inside = bool(np.all(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0] >= 0.0))
    return 0.0 if inside else gap


class BoxShape:
    """A bounding box standing on the table, ``ex`` x ``ey`` (m) about its base centre: its footprint is the
    rectangle, placed as its outline on the table (for ``polygon_distance``)."""

    def __init__(self, ex: float, ey: float):
        hx, hy = 0.5 * float(ex), 0.5 * float(ey)
        self.footprint = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        self.radius = math.hypot(hx, hy)

    def posed(self, placement: Placement) -> np.ndarray:
        return footprint_at(self.footprint, placement)


class TableLayout:
    """Objects placed so far, with the rule for where the next one may go; ``distance(a, b)`` measures two
    shapes placed (``Shape.posed``), <= 0 when they touch or overlap."""

    def __init__(self, reach_x, reach_y, table_x, table_y, margin: float, robot_clearance: float = 0.0,
                 distance: Callable[[Any, Any], float] = polygon_distance):
        self.reach_x, self.reach_y = tuple(reach_x), tuple(reach_y)
        self.table_x, self.table_y = tuple(table_x), tuple(table_y)
        self.margin = margin
        self.robot_clearance = robot_clearance
        self.distance = distance
        self.shapes: list[Shape] = []
        self.placements: list[Placement] = []
        self._posed: list = []

    @classmethod
    def on_stage(cls, stage: Stage, distance: Callable[[Any, Any], float] = polygon_distance) -> "TableLayout":
        """A layout in ``stage``'s reach area on its table top, with its clearances."""
        return cls(*stage.reach, *stage.top, stage.object_margin, stage.robot_clearance, distance)

    def fits_table(self, shape: Shape, placement: Placement) -> bool:
        """On the table, and clear of the robot's base (at the origin) by ``robot_clearance``."""
        if not fits(shape.footprint, placement, self.table_x, self.table_y):
            return False
        return self.robot_clearance <= 0.0 or \
            distance_to_point(shape.footprint, placement, (0.0, 0.0)) >= self.robot_clearance

    def clearance(self, shape: Shape, placement: Placement) -> float:
        """Least distance to any placed object (``inf`` when none is within reach of the margin)."""
        candidate = None
        best = math.inf
        for other_shape, other, other_posed in zip(self.shapes, self.placements, self._posed):
            centre_gap = math.hypot(placement.x - other.x, placement.y - other.y) - shape.radius - other_shape.radius
            if centre_gap > self.margin:
                continue  # the vertical cylinders around both shapes are already apart by more than the margin
            if candidate is None:
                candidate = shape.posed(placement)
            best = min(best, self.distance(candidate, other_posed))
            if best < self.margin:
                break
        return best

    def try_place(self, shape: Shape, rng: np.random.Generator, tries: int) -> Placement | None:
        """Sample up to ``tries`` poses; keep and return the first that is on the table and clear of the others."""
        for _ in range(tries):
            placement = Placement(float(rng.uniform(*self.reach_x)), float(rng.uniform(*self.reach_y)),
                                  float(rng.uniform(-math.pi, math.pi)))
            if not self.fits_table(shape, placement):
                continue
            gap = self.clearance(shape, placement)
            if gap < self.margin or gap <= 0.0:  # touching is never allowed, even with a zero margin
                continue
            self.shapes.append(shape)
            self.placements.append(placement)
            self._posed.append(shape.posed(placement))
            return placement
        return None

"""Mesh-level placement on the table: python-fcl distance queries between the objects' triangle meshes.

A bounding-circle test only skips pairs that are certainly far apart; every pair that could be closer than the
margin is decided by FCL's exact mesh distance, so concave shapes (a mug's handle over a plate) pack as they are.
"""
from __future__ import annotations

import collections
import math
import threading
from dataclasses import dataclass

import numpy as np

from muble.core.objects import ObjectModel
from muble.generation.mesh_keys import mesh_key
from muble.stage.geometry import hull_2d, yaw_matrix, yaw_quat


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


class CollisionMesh:
    """An object's mesh as an FCL BVH, built once and moved by transforms."""

    def __init__(self, model: ObjectModel):
        import fcl

        v = np.asarray(model.visual.vertices, dtype=np.float64)
        f = np.asarray(model.visual.faces, dtype=np.int32)
        bvh = fcl.BVHModel()
        bvh.beginModel(len(v), len(f))
        bvh.addSubModel(v, f)
        bvh.endModel()
        self.geometry = bvh
        self.vertices = v
        self.radius = float(np.linalg.norm(v[:, :2], axis=1).max())  # about the base centre's vertical axis
        # The footprint's extremes in any direction lie on its convex hull, so the table test needs only those.
        self.footprint = hull_2d(v[:, :2])

    def fits(self, placement: Placement, x_range, y_range) -> bool:
        """Whether the whole footprint at ``placement`` lies within ``x_range`` x ``y_range``."""
        c, s = math.cos(placement.yaw), math.sin(placement.yaw)
        fx, fy = self.footprint[:, 0], self.footprint[:, 1]
        x = fx * c - fy * s + placement.x
        y = fx * s + fy * c + placement.y
        return bool(x.min() >= x_range[0] and x.max() <= x_range[1] and y.min() >= y_range[0]
                    and y.max() <= y_range[1])

    def distance_to_point(self, placement: Placement, point_xy) -> float:
        """Least distance (m) from the footprint at ``placement`` to a point of the table plane (0 if inside)."""
        c, s = math.cos(placement.yaw), math.sin(placement.yaw)
        fx, fy = self.footprint[:, 0], self.footprint[:, 1]
        hull = np.stack([fx * c - fy * s + placement.x, fx * s + fy * c + placement.y], axis=1)
        a, b = hull, np.roll(hull, -1, axis=0)
        ab, ap = b - a, np.asarray(point_xy, dtype=float) - a
        t = np.clip(np.einsum("ij,ij->i", ap, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18), 0.0, 1.0)
        gap = float(np.linalg.norm(ap - t[:, None] * ab, axis=1).min())
        # Inside a counter-clockwise convex hull the point is left of every edge.
        inside = bool(np.all(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0] >= 0.0))
        return 0.0 if inside else gap

    def collision_object(self, placement: Placement):
        import fcl

        return fcl.CollisionObject(self.geometry, fcl.Transform(yaw_matrix(placement.yaw), placement.position))


class CollisionMeshCache:
    """``CollisionMesh`` per distinct visual mesh (by content), least recently used dropped first."""

    def __init__(self, max_entries: int = 512):
        self.max_entries = max_entries
        self._entries: collections.OrderedDict[bytes, CollisionMesh] = collections.OrderedDict()

    def get(self, model: ObjectModel) -> CollisionMesh:
        key = mesh_key(model)
        mesh = self._entries.get(key)
        if mesh is None:
            mesh = self._entries[key] = CollisionMesh(model)
            while len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)
        else:
            self._entries.move_to_end(key)
        return mesh


_SHARED = threading.local()


def shared_collision_meshes() -> CollisionMeshCache:
    """This thread's ``CollisionMeshCache``, shared by its generators (BVHs are read-only once built)."""
    cache = getattr(_SHARED, "cache", None)
    if cache is None:
        cache = _SHARED.cache = CollisionMeshCache()
    return cache


def mesh_distance(a, b) -> float:
    """Exact distance between two FCL collision objects (<= 0 when they touch or overlap)."""
    import fcl

    request = fcl.DistanceRequest(enable_signed_distance=False)
    result = fcl.DistanceResult()
    return float(fcl.distance(a, b, request, result))


class TableLayout:
    """Objects placed so far, with the rule for where the next one may go."""

    def __init__(self, reach_x, reach_y, table_x, table_y, margin: float, robot_clearance: float = 0.0):
        self.reach_x, self.reach_y = tuple(reach_x), tuple(reach_y)
        self.table_x, self.table_y = tuple(table_x), tuple(table_y)
        self.margin = margin
        self.robot_clearance = robot_clearance
        self.meshes: list[CollisionMesh] = []
        self.placements: list[Placement] = []
        self._objects: list = []

    def fits_table(self, mesh: CollisionMesh, placement: Placement) -> bool:
        """On the table, and clear of the robot's base (at the origin) by ``robot_clearance``."""
        if not mesh.fits(placement, self.table_x, self.table_y):
            return False
        return self.robot_clearance <= 0.0 or mesh.distance_to_point(placement, (0.0, 0.0)) >= self.robot_clearance

    def clearance(self, mesh: CollisionMesh, placement: Placement) -> float:
        """Least mesh distance to any placed object (``inf`` when none is within reach of the margin)."""
        candidate = None
        best = math.inf
        for other_mesh, other, other_obj in zip(self.meshes, self.placements, self._objects):
            centre_gap = math.hypot(placement.x - other.x, placement.y - other.y) - mesh.radius - other_mesh.radius
            if centre_gap > self.margin:
                continue  # the vertical cylinders around both meshes are already apart by more than the margin
            if candidate is None:
                candidate = mesh.collision_object(placement)
            best = min(best, mesh_distance(candidate, other_obj))
            if best < self.margin:
                break
        return best

    def try_place(self, mesh: CollisionMesh, rng: np.random.Generator, tries: int) -> Placement | None:
        """Sample up to ``tries`` poses; keep and return the first that is on the table and clear of the others."""
        for _ in range(tries):
            placement = Placement(float(rng.uniform(*self.reach_x)), float(rng.uniform(*self.reach_y)),
                                  float(rng.uniform(-math.pi, math.pi)))
            if not self.fits_table(mesh, placement):
                continue
            gap = self.clearance(mesh, placement)
            if gap < self.margin or gap <= 0.0:  # touching is never allowed, even with a zero margin
                continue
            self.meshes.append(mesh)
            self.placements.append(placement)
            self._objects.append(mesh.collision_object(placement))
            return placement
        return None


def min_pairwise_distance(meshes: list[CollisionMesh], placements: list[Placement]) -> float:
    """The least exact mesh distance over all pairs (for validation)."""
    objs = [m.collision_object(p) for m, p in zip(meshes, placements)]
    best = math.inf
    for i in range(len(objs)):
        for j in range(i + 1, len(objs)):
            best = min(best, mesh_distance(objs[i], objs[j]))
    return best

"""Mesh-level placement on the table: python-fcl distance queries between the objects' triangle meshes.

The generator's layouts are drawn by the one layout sampler (``muble.stage.layout.TableLayout``) with the objects'
meshes as shapes: a bounding-circle test only skips pairs that are certainly far apart; every pair that could be
closer than the margin is decided by FCL's exact mesh distance, so concave shapes (a mug's handle over a plate)
pack as they are.
"""
from __future__ import annotations

import collections
import math
import threading

import numpy as np

from muble.core.objects import ObjectModel
from muble.generation.mesh_keys import mesh_key
from muble.stage.geometry import hull_2d, yaw_matrix
from muble.stage.layout import Placement


class CollisionMesh:
    """An object's mesh as an FCL BVH, built once and moved by transforms: a shape of the layout sampler
    (``muble.stage.layout.Shape``), measured by ``mesh_distance``."""

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

    def posed(self, placement: Placement):
        """The mesh at ``placement`` as an FCL collision object (``mesh_distance`` measures two)."""
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


def min_pairwise_distance(meshes: list[CollisionMesh], placements: list[Placement]) -> float:
    """The least exact mesh distance over all pairs (for validation)."""
    objs = [m.posed(p) for m, p in zip(meshes, placements)]
    best = math.inf
    for i in range(len(objs)):
        for j in range(i + 1, len(objs)):
            best = min(best, mesh_distance(objs[i], objs[j]))
    return best

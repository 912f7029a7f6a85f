"""An in-memory cache of built geometry: meshes and the mass-independent data derived from them.

Loading a model's ``.npz`` and integrating its convex parts' mass properties costs ~10 ms an object, while a
scene generator builds thousands of objects from a few dozen (model, scale) pairs. Everything that depends only
on the geometry is kept here per (category, model, scale, params, geometry version): the meshes, the centre of
mass, the inertia of one kilogram (inertia is linear in mass for a uniform fill, so a build scales it), the
extents and the UVs. Weight, colour and stiffness vary per spec and are applied by the build itself.

Cached arrays are shared by every model built from them and are made read-only, so an accidental in-place edit
fails loudly instead of changing other objects.
"""
from __future__ import annotations

import collections
import json
import threading
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from muble.core.objects import ObjectSpec

from muble_plugins.objects.category import Geometry
from muble_plugins.objects.geometry import GEOMETRY_VERSION, mass_properties, planar_uv

DEFAULT_MAX_ENTRIES = 512  # SHOP-VRB2 has ~100 (model, scale) pairs; a few MB each at most


class GeometrySource(Protocol):
    """What the cache needs of an object set (``muble_plugins.objects.catalogue.CatalogueObjectSet`` is one): its
    name, part of every key, and the geometry of a spec, made or loaded on a miss."""

    set_name: str

    def geometry(self, spec: ObjectSpec) -> Geometry: ...


@dataclass(frozen=True)
class BuiltGeometry:
    """A model's geometry at one scale with its mass-independent properties."""

    geometry: Geometry
    com: np.ndarray  # (3,) centre of mass of the uniformly filled convex parts
    unit_inertia: np.ndarray  # (3, 3) inertia about ``com`` for a mass of 1 kg
    extents: np.ndarray  # (3,) bounding-box size of the visual mesh
    uv: np.ndarray  # (V, 2) the geometry's own UVs, else cylindrical ones


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.flags.writeable = False
    return a


def _derive(geometry: Geometry) -> BuiltGeometry:
    for part in [geometry.visual, *geometry.collision_parts]:
        _frozen(part.vertices)
        _frozen(part.faces)
    com, unit_inertia = mass_properties(geometry.collision_parts, 1.0)
    vertices = geometry.visual.vertices
    uv = geometry.uv if geometry.uv is not None else planar_uv(vertices)
    return BuiltGeometry(geometry, _frozen(com), _frozen(unit_inertia), _frozen(np.ptp(vertices, axis=0)),
                         _frozen(uv))


class BuildCache:
    """A bounded least-recently-used map from a geometry key to its ``BuiltGeometry`` (thread-safe)."""

    def __init__(self, max_entries: int = DEFAULT_MAX_ENTRIES):
        self.max_entries = max_entries
        self._entries: collections.OrderedDict[str, BuiltGeometry] = collections.OrderedDict()
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    @staticmethod
    def key(object_set: GeometrySource, spec: ObjectSpec) -> str:
        # The category is part of the key so a hit also means the (category, model) pair was validated.
        return json.dumps([object_set.set_name, spec.category, spec.model, round(float(spec.scale), 6), spec.params,
                           GEOMETRY_VERSION], sort_keys=True, default=str)

    def get(self, object_set: GeometrySource, spec: ObjectSpec) -> BuiltGeometry:
        key = self.key(object_set, spec)
        with self._lock:
            built = self._entries.get(key)
            if built is not None:
                self._entries.move_to_end(key)
                self.hits += 1
                return built
        built = _derive(object_set.geometry(spec))  # validates category and model, loads or generates
        with self._lock:
            self.misses += 1
            self._entries[key] = built
            while len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)
        return built

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()


def built_geometry(object_set: GeometrySource, spec: ObjectSpec) -> BuiltGeometry:
    """``spec``'s geometry and unit-mass properties from ``object_set``'s in-memory cache (made on first use)."""
    cache = object_set.__dict__.get("build_cache")
    if cache is None:
        cache = object_set.__dict__.setdefault("build_cache", BuildCache())
    return cache.get(object_set, spec)

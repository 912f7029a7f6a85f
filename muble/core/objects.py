"""What an ObjectSet hands to the simulator and the renderers: object descriptions and built models.

An ``ObjectSpec`` is a sampled description (which model, which attributes, which weight); an ``ObjectModel``
is everything needed to simulate and draw it. Both are plain data so that the environment, the scene
generator and every renderer can consume any object set without knowing it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

GRASP_TYPES = ("cylinder", "rim", "handle", "box")
MATERIAL_CLASSES = ("plastic", "metal", "glass", "rubber", "wood", "ceramic")


@dataclass
class ObjectSpec:
    """A sampled object: the catalogue entry and its attributes.

    ``weight_g`` becomes the MuJoCo body mass; ``stiffness`` (N/m) the contact stiffness that ``squeeze``
    measures. ``scale`` multiplies the model's nominal size; ``size`` is the word for it.
    """

    object_set: str
    category: str  # SHOP-VRB2 "name", e.g. "wine glass"
    model: str  # SHOP-VRB2 "file", e.g. "wine_glass1"
    colour: str
    material: str
    size: str  # "small" | "medium-sized" | "large"
    shape: str  # "flat", "hemisphere", "cuboid", "cylindrical", "irregularly shaped" …
    scale: float
    weight_g: float
    stiffness: float
    friction: float = 1.0
    params: dict[str, Any] = field(default_factory=dict)  # extra model parameters that change the geometry


@dataclass
class MeshPart:
    """A triangle mesh in object coordinates (metres, z up, origin at the centre of the base)."""

    vertices: np.ndarray  # (V, 3) float
    faces: np.ndarray  # (F, 3) int


@dataclass
class GraspFrame:
    """A grasp pose in object coordinates: gripper position and orientation (w, x, y, z), and opening (m)."""

    position: np.ndarray
    quat: np.ndarray
    width: float


@dataclass
class ObjectModel:
    """A built model: meshes for drawing and colliding, mass properties, contact and grasp data.

    ``collision_parts`` are convex and follow the real shape (a bowl is many parts so it can hold things).
    ``uv`` gives per-vertex texture coordinates of ``visual`` (or ``None`` for generated coordinates).
    ``inertia`` is the full 3×3 tensor about ``com`` in object coordinates (kg·m²).

    Hidden physical properties (docs/physical_properties.md); their defaults leave the simulated object as it
    is without them (the same MJCF):
    ``friction_coefficient`` is the object's own Coulomb coefficient, which then decides its contacts (with the
    table, the fingers, other objects whose own is lower); ``None``: ``friction`` is MuJoCo's geom friction,
    mixed with the other geom's by the maximum. ``com_offset`` (m, object frame, 2 or 3 values) puts the centre
    of mass off the geometric centre: horizontally off the origin (the centre of the base), vertically off
    ``com``. ``contents_mass`` (kg, part of ``mass``) is a loose body inside a closed container (``closed``): it
    rattles when the container is shaken.
    """

    spec: ObjectSpec
    visual: MeshPart
    collision_parts: list[MeshPart]
    mass: float  # kg, equals spec.weight_g / 1000
    com: np.ndarray
    inertia: np.ndarray
    friction: float
    stiffness: float  # N/m
    damping: float  # N·s/m
    rgba: tuple[float, float, float, float]
    material_class: str  # one of MATERIAL_CLASSES
    grasp_type: str  # one of GRASP_TYPES
    grasp_frames: list[GraspFrame]
    pickupable: bool
    stackable: bool
    stack_base: bool
    extents: np.ndarray  # (3,) full size of the axis-aligned bounding box in object coordinates
    uv: np.ndarray | None = None
    friction_coefficient: float | None = None  # the object's own sliding friction, deciding its contacts
    com_offset: np.ndarray | None = None  # (2,) or (3,) m, object frame: the centre of mass off the geometric centre
    contents_mass: float = 0.0  # kg of loose contents inside (part of ``mass``); 0: none
    closed: bool = False  # a closed container, which can hold loose contents

    @property
    def centre_of_mass(self) -> np.ndarray:
        """The body's centre of mass (3,) in object coordinates: ``com``, or with ``com_offset`` (x, y) off the
        origin and (z) off ``com``'s height."""
        com = np.asarray(self.com, dtype=float)
        if self.com_offset is None:
            return com.copy()
        given = np.asarray(self.com_offset, dtype=float).reshape(-1)
        if len(given) not in (2, 3):
            raise ValueError(f"com_offset has {len(given)} values; give (x, y) or (x, y, z) in metres")
        return np.array([given[0], given[1], com[2] + (given[2] if len(given) == 3 else 0.0)])

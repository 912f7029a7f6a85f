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

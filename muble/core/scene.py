"""The scene graph: the single source of truth shared by MuJoCo and every renderer.

It reads and writes the original SHOP-VRB2 scene schema (``objects[]`` with ``3d_coords``, ``orientation`` as
w, x, y, z, ``weight_gt``, ``bbox``, COCO RLE ``mask`` …). Keys this module does not model are kept in ``extra``
so that a file loads and saves without loss.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class RLE:
    """A COCO run-length-encoded mask, kept as data (``size`` = [height, width])."""

    size: list[int]
    counts: str

    def to_dict(self) -> dict[str, Any]:
        return {"size": list(self.size), "counts": self.counts}


@dataclass
class SceneObject:
    """One object of a scene. ``id`` is its index in the scene unless the file says otherwise."""

    id: int
    model: str  # "file": the model name, e.g. "mug2"
    name: str  # the category, e.g. "mug"
    shape: str
    size: str
    material: str
    colour: str
    position: np.ndarray  # "3d_coords", metres
    orientation: np.ndarray  # unit quaternion w, x, y, z
    weight_gt: float | None  # grams; None in an agent's view (muble.core.observation)
    stackable: bool
    stack_base: bool
    pickupable: bool
    weight: float | None = None  # measured, grams; None until weighed
    rotation: float | None = None  # yaw in degrees
    pixel_coords: list | None = None
    movability: str | None = None
    bbox: dict[str, float] | list | None = None  # extents {x, y, z} in its own frame, or eight corners
    scale_factor: float | None = None
    mask: RLE | None = None
    stiffness: float | None = None  # ground-truth contact stiffness, N/m
    extra: dict[str, Any] = field(default_factory=dict)
    explicit_id: bool = False

    @property
    def yaw(self) -> float:
        """Rotation about the world z axis in radians, from the quaternion."""
        w, x, y, z = self.orientation
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


# The original release's Blender import scale of its objects: 0.6 for its bigger variant, 0.45 for the smaller.
# This project's scale factors are multiples of the medium size, never below 0.85, so a factor of 0.6 or less marks
# an object of the original's files.
LARGEST_ORIGINAL_SCALE = 0.6


@dataclass
class SceneGraph:
    """A tabletop scene: objects, camera, lamps, masks and spatial relationships."""

    objects: list[SceneObject] = field(default_factory=list)
    split: str = ""
    image_index: int = 0
    image_filename: str = ""
    directions: dict[str, list[float]] | None = None
    camera_params: dict[str, Any] | None = None
    lamp_params: dict[str, list[float]] | None = None
    table: dict[str, Any] | None = None  # {"mask": RLE} in SHOP-VRB2 files
    robot: dict[str, Any] | None = None
    relationships: dict[str, list[list[int]]] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def object(self, obj_id: int) -> SceneObject:
        for obj in self.objects:
            if obj.id == obj_id:
                return obj
        raise KeyError(f"no object with id {obj_id}; ids in this scene: {[o.id for o in self.objects]}")

    @property
    def from_original_release(self) -> bool:
        """Whether this is a scene of the original release's files: every object at the original's import scale
        (``LARGEST_ORIGINAL_SCALE``)."""
        return bool(self.objects) and all(o.scale_factor is not None and o.scale_factor <= LARGEST_ORIGINAL_SCALE
                                          + 1e-9 for o in self.objects)

    @property
    def ids(self) -> list[int]:
        return [o.id for o in self.objects]

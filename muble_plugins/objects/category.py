"""A catalogue's entries: a ``Category``, the ``Finish``es it comes in and the ``Geometry`` its shape functions make.

Plain data, importing no other module of this package, so that the catalogue (``muble_plugins.objects.catalogue``,
which re-exports them), its in-memory build cache (``build_cache``) and its held-out filters (``heldout``) all
import them from here and none of those imports another for its types.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from muble.core.objects import GraspFrame, MeshPart


@dataclass
class Geometry:
    """What a shape function produces, in metres, for one scale."""

    visual: MeshPart
    collision_parts: list[MeshPart]
    grasp_frames: list[GraspFrame]
    uv: np.ndarray | None = None


@dataclass(frozen=True)
class Finish:
    """A material a category comes in, its medium-size weight range (g) and the colours it takes."""

    material: str
    weight_g: tuple[float, float]
    colours: tuple[str, ...]


@dataclass(frozen=True)
class Category:
    name: str
    variants: dict[str, tuple[str, Callable[[float], Geometry]]]  # model -> (shape word, geometry(scale))
    finishes: tuple[Finish, ...]
    grasp_type: str
    pickupable: bool
    stackable: bool
    stack_base: bool
    sizes: tuple[str, ...] = ("small", "medium-sized", "large")
    mass_exponent: float = 2.0  # mass ∝ scale^e: 2 for thin-walled shells, 3 for solid or filled items
    closed: bool = False  # a closed container (a can, a flask, a food box): it can hold loose contents
    # The hidden physical properties its objects carry (``ObjectSet.physical_properties``): none by default.
    physical_properties: tuple[str, ...] = ()
    # Models built when a scene names them but never sampled (so that adding one changes no generated scene):
    # the original SHOP-VRB2 models this catalogue does not sample.
    imported_variants: dict[str, tuple[str, Callable[[float], Geometry]]] = field(default_factory=dict)

    def model(self, name: str) -> tuple[str, Callable[[float], Geometry]] | None:
        """(shape word, geometry function) of a sampled or imported model, ``None`` if unknown."""
        return self.variants.get(name) or self.imported_variants.get(name)

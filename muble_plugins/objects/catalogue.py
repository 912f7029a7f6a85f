"""The machinery every object catalogue shares: categories, sampling, the mesh cache and model assembly.

A catalogue is a table of ``Category`` entries (``muble_plugins.objects.category``, re-exported here). Each category lists its shape variants (a geometry function of
the scale factor), the materials it comes in (each with a weight range and the colours that material takes),
its flags and grasp type. ``CatalogueObjectSet`` samples specs from the table and builds ``ObjectModel``s,
caching generated meshes on disk keyed by object set, model, scale and geometry version.
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from muble import ConfigError, ObjectSet
from muble.core.errors import unknown_name
from muble.core.objects import GraspFrame, MeshPart, ObjectModel, ObjectSpec
from muble.core.object_physics import realised_damping, realised_stiffness
from muble.core.ranges import bounded, configured

from muble_plugins.common.materials import STIFFNESS_RANGE  # ground-truth stiffness by material (N/m)
from muble_plugins.objects.build_cache import built_geometry
from muble_plugins.objects.category import Category, Finish, Geometry  # noqa: F401 - Finish re-exported for callers
from muble_plugins.objects.geometry import GEOMETRY_VERSION
from muble_plugins.objects.geometry import mass_properties, planar_uv  # noqa: F401 - re-exported for callers
from muble_plugins.objects.heldout import check_property_range, sample_range_part, sampled_categories

log = logging.getLogger(__name__)

SIZE_SCALES = {"small": 0.85, "medium-sized": 1.0, "large": 1.15}

# Words used in SHOP-VRB2 files -> the renderers' material classes.
MATERIAL_CLASS = {"plastic": "plastic", "metal": "metal", "glass": "glass", "rubber": "rubber",
                  "wooden": "wood", "ceramic": "ceramic"}

COLOUR_RGBA = {
    "red": (0.80, 0.10, 0.10, 1.0), "blue": (0.12, 0.25, 0.80, 1.0), "green": (0.12, 0.60, 0.20, 1.0),
    "brown": (0.45, 0.28, 0.14, 1.0), "purple": (0.48, 0.18, 0.65, 1.0), "cyan": (0.10, 0.70, 0.75, 1.0),
    "yellow": (0.92, 0.80, 0.12, 1.0), "gray": (0.50, 0.50, 0.52, 1.0), "white": (0.92, 0.92, 0.90, 1.0),
    "black": (0.06, 0.06, 0.07, 1.0), "transparent": (0.85, 0.92, 0.95, 0.30),
    "metallic": (0.75, 0.76, 0.78, 1.0),
}
PAINTS = ("red", "blue", "green", "brown", "purple", "cyan", "yellow")


def default_stiffness(material: str) -> float | None:
    """The stiffness (N/m) of an object of ``material`` whose scene gives none: the centre (geometric mean) of the
    material's sampling range, where a log-uniform sample falls in the middle; ``None`` for an unknown material."""
    if material not in STIFFNESS_RANGE:
        return None
    low, high = STIFFNESS_RANGE[material]
    return round(math.sqrt(low * high), 1)


# Coulomb friction against the table (typical dry sliding coefficients of the surface materials).
FRICTION = {"rubber": 1.1, "plastic": 0.6, "metal": 0.5, "wooden": 0.6, "glass": 0.6, "ceramic": 0.6}


def grasp_quat(closing, approach) -> np.ndarray:
    """Quaternion (w, x, y, z) of a grasp frame: its origin is where the middle of the finger pads goes, its x
    axis the fingers' closing direction and its z axis points from the hand into the object. The primitives map
    it to the grip site of whichever gripper is mounted (``muble_plugins.primitives.grasping.GripGeometry``)."""
    x = np.asarray(closing, dtype=float)
    z = np.asarray(approach, dtype=float)
    x, z = x / np.linalg.norm(x), z / np.linalg.norm(z)
    return Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z])).as_quat(scalar_first=True)


def top_down(position, yaw: float, width: float) -> GraspFrame:
    """A top-down grasp at ``position``: the hand points straight down and the fingers close along the
    horizontal direction (-sin yaw, cos yaw), i.e. across the object's y axis turned by ``yaw``.

    The frame is where the pads' middle goes (x: closing direction, z: approach); ``width`` is the object's
    extent between the pads (what they close on: a gripper must open wider and close narrower than that).
    """
    closing = (-math.sin(yaw), math.cos(yaw), 0.0)
    return GraspFrame(np.asarray(position, dtype=float), grasp_quat(closing, (0.0, 0.0, -1.0)), float(width))


def side(position, approach_yaw: float, width: float, pitch: float = 0.0, closing: str = "horizontal"
         ) -> GraspFrame:
    """A grasp approaching along the horizontal direction ``approach_yaw``, tilted down by ``pitch`` (0 =
    horizontal, pi/2 = from above); the fingers close horizontally (across a handle or stem) or, with
    ``closing="vertical"``, in the vertical plane of the approach (across a board's thickness)."""
    c, s = math.cos(approach_yaw), math.sin(approach_yaw)
    approach = (c * math.cos(pitch), s * math.cos(pitch), -math.sin(pitch))
    if closing == "horizontal":
        across = (-s, c, 0.0)
    elif closing == "vertical":
        across = (c * math.sin(pitch), s * math.sin(pitch), math.cos(pitch))
    else:
        raise ValueError(f"closing must be 'horizontal' or 'vertical', not {closing!r}")
    return GraspFrame(np.asarray(position, dtype=float), grasp_quat(across, approach), float(width))


class MeshCache:
    """Generated geometry on disk, one ``.npz`` per (object set, model, scale, geometry version)."""

    def __init__(self, directory: str | os.PathLike | None):
        self.directory = Path(directory) if directory else None

    @staticmethod
    def key(object_set: str, model: str, scale: float, params: dict) -> str:
        text = json.dumps([object_set, model, round(scale, 6), params, GEOMETRY_VERSION], sort_keys=True)
        return f"{model}-{hashlib.sha1(text.encode()).hexdigest()[:16]}"

    def load(self, key: str) -> Geometry | None:
        if self.directory is None:
            return None
        path = self.directory / f"{key}.npz"
        if not path.exists():
            return None
        with np.load(path) as data:
            n = int(data["n_parts"])
            parts = [MeshPart(data[f"cv{i}"], data[f"cf{i}"]) for i in range(n)]
            frames = [GraspFrame(p, q, float(w)) for p, q, w in zip(data["gp"], data["gq"], data["gw"])]
            uv = data["uv"] if data["uv"].size else None
            return Geometry(MeshPart(data["vv"], data["vf"]), parts, frames, uv)

    def store(self, key: str, geometry: Geometry) -> None:
        """Keep ``geometry`` on disk for the next run. The cache only saves time: a folder that cannot be written
        (an unwritable HOME, a full disk) turns it off for this process, with one warning, and the run goes on."""
        if self.directory is None:
            return
        try:
            self._store(key, geometry)
        except OSError as e:
            log.warning("object mesh cache %s cannot be written (%s); meshes are rebuilt each run. Set "
                        "MUBLE_CACHE_DIR to a writable folder to keep them", self.directory, e.strerror or e)
            self.directory = None

    def _store(self, key: str, geometry: Geometry) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        arrays = {"vv": geometry.visual.vertices, "vf": geometry.visual.faces,
                  "n_parts": np.array(len(geometry.collision_parts)),
                  "uv": geometry.uv if geometry.uv is not None else np.zeros((0, 2)),
                  "gp": np.array([f.position for f in geometry.grasp_frames]).reshape(-1, 3),
                  "gq": np.array([f.quat for f in geometry.grasp_frames]).reshape(-1, 4),
                  "gw": np.array([f.width for f in geometry.grasp_frames])}
        for i, part in enumerate(geometry.collision_parts):
            arrays[f"cv{i}"], arrays[f"cf{i}"] = part.vertices, part.faces
        # Write then rename so parallel workers never read a half-written file.
        tmp = self.directory / f"{key}.{os.getpid()}.tmp.npz"
        np.savez_compressed(tmp, **arrays)
        os.replace(tmp, self.directory / f"{key}.npz")


def default_cache_dir() -> str:
    return os.environ.get("MUBLE_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "muble", "objects"))


class CatalogueObjectSet(ObjectSet):
    """An ``ObjectSet`` backed by a table of ``Category`` entries.

    The held-out options restrict what ``sample`` draws without touching what ``build`` builds (a scene that
    names an excluded model still loads): ``exclude_models``/``only_models`` name models of the catalogue's
    ``variants``, ``exclude_finishes``/``only_finishes`` colour-material combinations ("red plastic"); a
    category left without a model or a finish is not sampled. ``property_range`` ("all", "inner", "outer")
    chooses the part of each weight range (linear) and stiffness range (log space) that is sampled
    (``muble_plugins.objects.heldout``). At their defaults every draw is the one the catalogue always made.

    Built from an ``ObjectSetConfig`` (the registry's checked instance) and/or keyword overrides of its fields
    (``ShopVrb2Objects(cache_dir=None)``), checked against the schema's types and bounds.
    """

    set_name = ""
    catalogue: dict[str, Category] = {}

    def __init__(self, config: ObjectSetConfig | None = None, **options):
        self.config = cfg = configured(ObjectSetConfig, config, options, owner=f"object_set '{self.set_name}'")
        # "" = the default cache folder, None = no disk cache.
        self.cache = MeshCache(default_cache_dir() if cfg.cache_dir == "" else cfg.cache_dir)
        self.damping_ratio = cfg.damping_ratio
        check_property_range(cfg.property_range)
        self.property_range = cfg.property_range
        self.inner_fraction = cfg.inner_fraction
        enabled = list(cfg.categories) or list(self.catalogue)
        for name in enabled:
            self._category(name)
        self._sampled = sampled_categories(self.catalogue, self.set_name, cfg.exclude_models, cfg.only_models,
                                           cfg.exclude_finishes, cfg.only_finishes)
        self._enabled = [name for name in enabled if name in self._sampled]
        if not self._enabled:
            raise ConfigError(f"{self.set_name}: the model and finish filters leave none of the categories "
                              f"{enabled} to sample; exclude fewer models or finishes")

    def categories(self) -> list[str]:
        """The categories ``sample`` draws from: the ``categories`` option less those the filters empty."""
        return list(self._enabled)

    def models(self, category: str) -> list[str]:
        """The models ``sample`` draws for ``category`` (after ``exclude_models``/``only_models``)."""
        self._category(category)
        sampled = self._sampled.get(category)
        return list(sampled.models) if sampled else []

    def _category(self, name: str) -> Category:
        if name not in self.catalogue:
            raise ConfigError(unknown_name(f"{self.set_name} category", name, list(self.catalogue)))
        return self.catalogue[name]

    def sample(self, rng: np.random.Generator, category: str | None = None) -> ObjectSpec:
        name = category if category is not None else self._enabled[int(rng.integers(len(self._enabled)))]
        cat = self._category(name)
        choice = self._sampled.get(name)
        if choice is None:
            raise ConfigError(f"{self.set_name} category '{name}' has no model or finish left to sample: the "
                              "exclude_/only_ options remove all of them")
        # One draw per attribute, in this order: the sampled stream of a scene depends on it.
        model = choice.models[int(rng.integers(len(choice.models)))]
        finish = choice.finishes[int(rng.integers(len(choice.finishes)))]
        colour = finish.colours[int(rng.integers(len(finish.colours)))]
        size = cat.sizes[int(rng.integers(len(cat.sizes)))]
        scale = SIZE_SCALES[size]
        low, high = finish.weight_g
        weight = sample_range_part(rng, low, high, self.property_range, self.inner_fraction) * scale**cat.mass_exponent
        k_low, k_high = STIFFNESS_RANGE[finish.material]
        stiffness = math.exp(sample_range_part(rng, math.log(k_low), math.log(k_high), self.property_range,
                                               self.inner_fraction))
        return ObjectSpec(object_set=self.set_name, category=name, model=model, colour=colour,
                          material=finish.material, size=size, shape=cat.variants[model][0], scale=scale,
                          weight_g=round(weight, 1), stiffness=round(stiffness, 1),
                          friction=FRICTION[finish.material])

    def default_stiffness(self, material: str) -> float | None:
        """Contact stiffness (N/m) for a scene object of ``material`` that has none (``default_stiffness``)."""
        return default_stiffness(material)

    def physical_properties(self, spec: ObjectSpec) -> tuple[str, ...]:
        """The hidden physical properties ``spec``'s category carries (``Category.physical_properties``)."""
        return self._category(spec.category).physical_properties

    def geometry(self, spec: ObjectSpec) -> Geometry:
        """The (cached) geometry of ``spec``'s model at its scale."""
        make = self.shape(self._category(spec.category), spec)
        key = MeshCache.key(self.set_name, spec.model, spec.scale, spec.params)
        geometry = self.cache.load(key)
        if geometry is None:
            geometry = make()
            self.cache.store(key, geometry)
            log.debug("generated %s at scale %.3f", spec.model, spec.scale)
        return geometry

    def shape(self, category: Category, spec: ObjectSpec) -> Callable[[], Geometry]:
        """What makes ``spec``'s geometry: its model's shape function at its scale. An object set whose specs can
        ask for another build (``spec.params``) overrides this."""
        variant = category.model(spec.model)
        if variant is None:
            raise ConfigError(unknown_name(f"'{spec.category}' model", spec.model,
                                           [*category.variants, *category.imported_variants]))
        return lambda: variant[1](spec.scale)

    def rgba(self, spec: ObjectSpec) -> tuple[float, ...]:
        """The colour ``spec`` is drawn in (``COLOUR_RGBA`` of its colour word). An object set whose specs can ask
        for another palette overrides this."""
        if spec.colour not in COLOUR_RGBA:
            raise ConfigError(unknown_name("colour", spec.colour, list(COLOUR_RGBA)))
        return COLOUR_RGBA[spec.colour]

    def build(self, spec: ObjectSpec) -> ObjectModel:
        cat = self._category(spec.category)
        built = built_geometry(self, spec)  # meshes and unit-mass properties, cached in memory per model and scale
        geometry = built.geometry
        mass = spec.weight_g / 1000.0
        com, inertia = built.com.copy(), built.unit_inertia * mass  # uniform fill: inertia is linear in mass
        stiffness = realised_stiffness(spec.stiffness, mass)
        if stiffness < spec.stiffness * 0.999:
            log.warning("%s: %.0f g is too light for %.0f N/m at a 2 ms step; using %.0f N/m",
                        spec.model, spec.weight_g, spec.stiffness, stiffness)
        rgba = self.rgba(spec)
        return ObjectModel(
            spec=spec, visual=geometry.visual, collision_parts=geometry.collision_parts, mass=mass, com=com,
            inertia=inertia, friction=spec.friction, stiffness=stiffness,
            damping=realised_damping(spec.stiffness, self.damping_ratio, mass),
            rgba=rgba, material_class=MATERIAL_CLASS[spec.material],
            grasp_type=cat.grasp_type, grasp_frames=geometry.grasp_frames, pickupable=cat.pickupable,
            stackable=cat.stackable, stack_base=cat.stack_base,
            extents=built.extents.copy(), uv=built.uv, closed=cat.closed,
        )


@dataclass
class ObjectSetConfig:
    """Options of a catalogue object set (the Hydra ``objects`` group)."""

    cache_dir: str | None = ""  # "" = $MUBLE_CACHE_DIR or ~/.cache/muble/objects; null = no disk cache
    categories: list[str] = field(default_factory=list)  # empty = every category of the set
    damping_ratio: float = 1.0  # contact damping relative to critical
    # Held-out conditions (docs/objects.md): what sampling may draw. Empty lists and "all" leave every scene as it
    # was. Models as in the catalogue's variants ("mug2"), finishes as "colour material" ("red plastic").
    exclude_models: list[str] = field(default_factory=list)
    only_models: list[str] = field(default_factory=list)  # empty = every model
    exclude_finishes: list[str] = field(default_factory=list)
    only_finishes: list[str] = field(default_factory=list)  # empty = every finish
    property_range: str = "all"  # all | inner | outer: the part of each weight and stiffness range sampled
    inner_fraction: float = bounded(0.6, gt=0, lt=1)  # the middle share of each range that "inner" keeps

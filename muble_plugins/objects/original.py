"""Scene objects of the original SHOP-VRB2 files, built with this catalogue's models.

The original release names 26 models (``ORIGINAL_MODELS``) and records a few things differently:
- ``scale_factor`` is the import scale of the original Blender model: 0.6 for its bigger variant (the size words
  "medium-sized" and "large"), 0.45 for the smaller one ("small"). Here it is the multiple of the medium size
  (``SIZE_SCALES``: small 0.85, medium-sized 1.0, large 1.15). A scale factor of 0.6 or less is read as the
  original's and converted: ``SIZE_SCALES[size] * scale_factor / ORIGINAL_SCALE[size]``, so a small object at
  0.45 and a medium-sized or large one at 0.6 are built at 0.85, 1.0 and 1.15, and other combinations in
  proportion (a medium-sized tray at 0.45: 0.75); this catalogue's own factors are never below 0.85. The
  original's objects are smaller than real ones (about 0.5-0.85 of this catalogue's at the same size word) and
  its scenes are laid out for them, so an object whose ``bbox`` records a smaller footprint is built at that
  footprint (``fitted_scale``), not below 0.5 of the medium size.
- the object's geometry is the original model's, measured and rebuilt here
  (``muble_plugins.objects.original_models``), at the file's import scale: ``spec.params`` names the original
  model and its ``scale_factor`` (``original_fit``), so that the masks and contacts of a scene match the
  original's. ``spec.model`` and ``spec.scale`` stay this catalogue's model and size multiple (the words of the
  object). An original-scale object naming a model the original does not have is built with this catalogue's
  model, fitted to its ``bbox`` as described above.
- a model's shape word can differ from this catalogue's model of the same name (the original food_box2 is
  "cylindrical", chopping_board2 "cuboid"); the object is then built with the category's model that has the
  file's shape word, so the geometry matches what instructions say about it.
- there is no stiffness or friction: ``object_models`` takes the material's default stiffness
  (``ObjectSet.default_stiffness``) and the object gets its material's friction (``FRICTION``).
- weights are ``weight_gt``, as everywhere (the body mass is the weight).
What cannot be mapped (an unknown category, model, shape word, size, material or colour) is a
``SceneValidationError`` naming the object and the field.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

from muble.core.errors import SceneValidationError, unknown_name
from muble.core.objects import ObjectSpec
from muble.core.scene import LARGEST_ORIGINAL_SCALE, SceneObject

from muble_plugins.common.materials import STIFFNESS_RANGE
from muble_plugins.objects.catalogue import COLOUR_RGBA, FRICTION, SIZE_SCALES, Category

# The original SHOP-VRB2 models per category (the "file" field of its scene files).
ORIGINAL_MODELS: dict[str, tuple[str, ...]] = {
    "baking tray": ("baking_tray1", "baking_tray2"),
    "bowl": ("bowl1", "bowl2", "bowl3"),
    "chopping board": ("chopping_board1", "chopping_board2", "chopping_board3"),
    "food box": ("food_box1", "food_box2"),
    "glass": ("glass1", "glass2", "glass3", "glass4", "glass5"),
    "mug": ("mug1", "mug2", "mug3"),
    "plate": ("plate1", "plate2"),
    "soda can": ("soda_can",),
    "thermos": ("thermos1", "thermos2"),
    "wine glass": ("wine_glass1", "wine_glass2", "wine_glass3"),
}
# The original's Blender import scale for each size word (its "bigger" and "smaller" variants).
ORIGINAL_SCALE = {"small": 0.45, "medium-sized": 0.6, "large": 0.6}
# The smallest multiple of the medium size an original object is fitted to (some original bounding boxes hold
# only part of the object: a wine glass's stem).
MIN_FITTED_SCALE = 0.5
# A friction given in the scene object's extra fields wins over the material's.
DEFAULT_FRICTION_KEY = "friction"
# The original release's paint colours (its scene generator's properties file, 0-255 per channel), which its
# Blender scenes took as linear reflectance; its white, black and grey objects keep their models' own finish, not
# recorded here. An object of its files is drawn in these (``original_rgba``).
ORIGINAL_PAINTS = {
    "red": (173, 35, 35), "blue": (42, 75, 215), "green": (29, 105, 20), "brown": (129, 74, 25),
    "purple": (129, 38, 192), "cyan": (41, 208, 208), "yellow": (255, 238, 51),
}
# ``ObjectSpec.params`` keys of an object built with the original release's model at its import scale.
ORIGINAL_MODEL_PARAM = "original_model"
ORIGINAL_SCALE_PARAM = "original_scale"


def is_original_scale(obj: SceneObject) -> bool:
    """Whether the object's ``scale_factor`` is the original release's import scale (0.6 or less)."""
    return obj.scale_factor is not None and obj.scale_factor <= LARGEST_ORIGINAL_SCALE + 1e-9


def nominal_scale(obj: SceneObject) -> float:
    """The multiple of the medium size the object's size word and scale factor stand for (see the module doc)."""
    if obj.size not in SIZE_SCALES:
        raise SceneValidationError(unknown_name("size", obj.size, list(SIZE_SCALES)), obj=obj.id, field="size")
    if obj.scale_factor is None:
        return SIZE_SCALES[obj.size]
    if is_original_scale(obj):
        return SIZE_SCALES[obj.size] * obj.scale_factor / ORIGINAL_SCALE[obj.size]
    return float(obj.scale_factor)


def fitted_scale(obj: SceneObject, footprint_at_unit_scale: float) -> float:
    """The scale an original object is built at: its nominal scale, reduced to the footprint its file's ``bbox``
    records (the original's objects are smaller than real ones, about 0.5-0.85 of this catalogue's, and its
    scenes are laid out for them), never below ``MIN_FITTED_SCALE``."""
    nominal = nominal_scale(obj)
    bbox = obj.bbox
    if not is_original_scale(obj) or not isinstance(bbox, dict) or footprint_at_unit_scale <= 0:
        return nominal
    fit = max(bbox["x"], bbox["y"]) / footprint_at_unit_scale
    return min(nominal, max(fit, MIN_FITTED_SCALE))


def original_fit(spec: ObjectSpec) -> tuple[str, float] | None:
    """(original model, import scale) that ``spec`` is built with, ``None`` for this catalogue's own build."""
    model = spec.params.get(ORIGINAL_MODEL_PARAM)
    if model is None:
        return None
    return str(model), float(spec.params[ORIGINAL_SCALE_PARAM])


def model_for(obj: SceneObject, category: Category) -> str:
    """The catalogue model that builds ``obj``: its own model if the shape word agrees, else the category's first
    model with the file's shape word."""
    known = {*category.variants, *category.imported_variants, *ORIGINAL_MODELS.get(category.name, ())}
    if obj.model not in known:
        raise SceneValidationError(unknown_name(f"'{category.name}' model", obj.model, sorted(known)),
                                   obj=obj.id, field="file")
    own = category.model(obj.model)
    if own is not None and own[0] == obj.shape:
        return obj.model
    shaped = [m for m, (shape, _) in {**category.variants, **category.imported_variants}.items()
              if shape == obj.shape]
    if not shaped:
        shapes = sorted({shape for shape, _ in {**category.variants, **category.imported_variants}.values()})
        raise SceneValidationError(unknown_name(f"shape of a {category.name}", obj.shape, shapes),
                                   obj=obj.id, field="shape")
    return shaped[0]


def spec_from_scene_object(obj: SceneObject, catalogue: dict[str, Category], set_name: str,
                           footprint: Callable[[ObjectSpec], float]) -> ObjectSpec:
    """The ``ObjectSpec`` that builds a scene object of either convention (this project's or the original's).

    ``footprint(spec)`` is the largest horizontal extent (m) of ``spec``'s model at its scale."""
    category = catalogue.get(obj.name)
    if category is None:
        raise SceneValidationError(unknown_name("category", obj.name, sorted(catalogue)), obj=obj.id, field="name")
    if obj.material not in STIFFNESS_RANGE:
        raise SceneValidationError(unknown_name("material", obj.material, sorted(STIFFNESS_RANGE)), obj=obj.id,
                                   field="material")
    if obj.colour not in COLOUR_RGBA:
        raise SceneValidationError(unknown_name("colour", obj.colour, sorted(COLOUR_RGBA)), obj=obj.id,
                                   field="colour")
    if obj.stiffness is None:
        raise SceneValidationError("is missing; object_models() fills it from the object set's material default",
                                   obj=obj.id, field="stiffness")
    original = is_original_scale(obj)
    friction = obj.extra.get(DEFAULT_FRICTION_KEY)
    if friction is None:
        # This project's scene files build with MuJoCo's friction of 1; original ones take the
        # material's.
        friction = FRICTION[obj.material] if original else 1.0
    spec = ObjectSpec(
        object_set=set_name, category=obj.name, model=model_for(obj, category), colour=obj.colour,
        material=obj.material, size=obj.size, shape=obj.shape, scale=nominal_scale(obj),
        weight_g=float(obj.weight_gt), stiffness=float(obj.stiffness), friction=float(friction),
        params=dict(obj.extra.get("params", {})),
    )
    if original and obj.model in ORIGINAL_MODELS.get(obj.name, ()):
        spec.params.update({ORIGINAL_MODEL_PARAM: obj.model, ORIGINAL_SCALE_PARAM: float(obj.scale_factor)})
    elif original:
        spec.scale = round(fitted_scale(obj, footprint(dataclasses.replace(spec, scale=1.0))), 4)
    return spec


def original_rgba(spec: ObjectSpec) -> tuple[float, float, float, float] | None:
    """The original release's colour of an object of its files (``ORIGINAL_PAINTS``), or ``None`` for any other
    object and for the colours it does not record."""
    if original_fit(spec) is None or spec.colour not in ORIGINAL_PAINTS:
        return None
    return (*(c / 255.0 for c in ORIGINAL_PAINTS[spec.colour]), 1.0)

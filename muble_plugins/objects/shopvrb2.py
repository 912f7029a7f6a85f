"""The SHOP-VRB2 household objects: ten categories, two or three procedural shape variants each.

Names follow the SHOP-VRB2 files: category ("name") words such as "chopping board" and "food box" (the paper's
food container), model ("file") names such as "mug2", material words such as "wooden". Dimensions are those of
common retail items at medium size (a mug 8 cm wide and 10 cm tall, a dinner plate 26 cm across).

Weights (grams, medium size; small and large scale them by scale² for shells, scale³ for filled or solid
items) are typical product weights of the category in that material, from retail listings of everyday items:
a 330-355 ml can full (340-390 g), an 11 oz stoneware mug (280-380 g), a 26 cm stoneware dinner plate
(450-650 g), a 30×20×1.8 cm hardwood board (~0.65 g/cm³: 550-850 g), a half-sheet aluminium/steel baking tray
(350-600 g), a 0.5 l stainless vacuum flask (250-400 g), a tumbler of soda-lime glass (180-300 g). The
weights in the original SHOP-VRB2 files are lighter (60-490 g); MuBlE uses the real ones.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from muble_plugins.objects import geometry as g
from muble import ConfigError
from muble.core.errors import unknown_name
from muble.core.objects import ObjectSpec
from muble.core.scene import SceneObject
from muble_plugins.objects import original
from muble_plugins.objects.build_cache import built_geometry
from muble_plugins.objects.catalogue import PAINTS, Category, CatalogueObjectSet, Finish, Geometry, side, top_down
from muble_plugins.objects.frames import (GRIP_DEPTH, STEM_GRIP_HEIGHT, cylinder_frames, handle_frames, radius_at,
                                          rim_frames, side_frames)
from muble_plugins.objects.original_models import ORIGINAL_GEOMETRY

CERAMIC_COLOURS = (*PAINTS, "white", "black")


def _scaled(points, s):
    return [(r * s, z * s) for r, z in points]


def _open_vessel(outer, wall, base, s, sectors=12) -> tuple[g.MeshPart, np.ndarray, list]:
    visual, uv, parts = g.container(_scaled(outer, s), wall * s, base * s, sectors=sectors)
    return visual, uv, parts


# --- bowls -----------------------------------------------------------------------------------------------

def _bowl(outer, wall, base):
    def build(s: float) -> Geometry:
        visual, uv, parts = _open_vessel(outer, wall, base, s)
        return Geometry(visual, parts, rim_frames(_scaled(outer, s), wall * s, 12), uv)
    return build


BOWL1 = [(0.035, 0.0), (0.052, 0.012), (0.065, 0.03), (0.073, 0.05), (0.075, 0.065)]  # round, 15 cm
BOWL2 = [(0.030, 0.0), (0.045, 0.01), (0.080, 0.07)]  # flared cereal bowl, 16 cm
BOWL3 = [(0.040, 0.0), (0.055, 0.012), (0.065, 0.04), (0.068, 0.08)]  # deep, 13.6 cm

# --- plates and trays ------------------------------------------------------------------------------------

def _plate(outer, wall, base):
    def build(s: float) -> Geometry:
        visual, uv, parts = _open_vessel(outer, wall, base, s, sectors=16)
        r, h = outer[-1][0] * s, outer[-1][1] * s
        frames = [side((r * math.cos(a), r * math.sin(a), h / 2), a + math.pi, 0.03, closing="vertical")
                  for a in np.arange(4) * math.pi / 2]
        return Geometry(visual, parts, frames, uv)
    return build


PLATE1 = [(0.085, 0.0), (0.10, 0.01), (0.125, 0.018), (0.13, 0.022)]  # dinner plate, 26 cm
PLATE2 = [(0.070, 0.0), (0.085, 0.02), (0.105, 0.032), (0.11, 0.035)]  # soup plate, 22 cm


def _rect_tray(sx, sy, sz, wall, base):
    def build(s: float) -> Geometry:
        visual, uv, parts = g.tray((sx * s, sy * s, sz * s), wall, base * s)
        frames = [top_down((sx * s / 2 - wall / 2, 0.0, sz * s - 0.01), 0.0, wall),
                  top_down((-sx * s / 2 + wall / 2, 0.0, sz * s - 0.01), 0.0, wall)]
        return Geometry(visual, parts, frames, uv)
    return build


# --- boards ----------------------------------------------------------------------------------------------

def _board(sx, sy, sz, corner, tab=None):
    def build(s: float) -> Geometry:
        visual, uv = g.rounded_box((sx * s, sy * s, sz * s), corner * s)
        parts = [visual]
        if tab is not None:  # a handle tab sticking out along +x: an "irregularly shaped" board
            tx, ty = tab
            handle, _ = g.rounded_box((tx * s + 0.02, ty * s, sz * s), 0.01)
            handle = g.MeshPart(handle.vertices + [sx * s / 2 + tx * s / 2 - 0.01, 0, 0], handle.faces)
            parts = [visual, handle]
            visual = g.concatenate(parts)
            uv = None
        frames = [side((0.0, sy * s / 2, sz * s / 2), -math.pi / 2, sz * s, closing="vertical"),
                  side((0.0, -sy * s / 2, sz * s / 2), math.pi / 2, sz * s, closing="vertical")]
        return Geometry(visual, parts, frames, uv)
    return build


# --- closed containers -----------------------------------------------------------------------------------

def _tub(radius, height, lid):
    def build(s: float) -> Geometry:
        r, h, t = radius * s, height * s, lid * s
        body = g.disc_part(r * 0.92, r, 0.0, h - t, 32)
        cap = g.disc_part(r * 1.03, r * 1.03, h - t, h, 32)
        parts = [body, cap]
        return Geometry(g.concatenate(parts), parts, cylinder_frames(r, h - 0.02), None)
    return build


def _box_container(sx, sy, sz):
    def build(s: float) -> Geometry:
        visual, uv = g.rounded_box((sx * s, sy * s, sz * s), 0.015 * s)
        frames = [top_down((0.0, 0.0, sz * s - 0.02), 0.0, sy * s)]
        return Geometry(visual, [visual], frames, uv)
    return build


# --- cups, cans, flasks -------------------------------------------------------------------------------------

def _glass(outer, wall, base):
    def build(s: float) -> Geometry:
        visual, uv, parts = _open_vessel(outer, wall, base, s, sectors=10)
        pts = _scaled(outer, s)
        z = pts[-1][1] - GRIP_DEPTH
        # Around the body near the top; a glass too wide for the fingers is pinched at the rim instead.
        mid = 0.5 * pts[-1][1]
        frames = cylinder_frames(radius_at(pts, z), z) + rim_frames(pts, wall * s, 10)
        return Geometry(visual, parts, frames + side_frames(radius_at(pts, max(mid, STEM_GRIP_HEIGHT)), mid), uv)
    return build


GLASS1 = [(0.033, 0.0), (0.035, 0.10)]  # straight tumbler
GLASS2 = [(0.028, 0.0), (0.04, 0.12)]  # tapered highball
GLASS3 = [(0.038, 0.0), (0.040, 0.08)]  # short old-fashioned
GLASS4 = [(0.030, 0.0), (0.036, 0.085)]  # tapered juice glass (the original SHOP-VRB2 glass4)


def _square_glass(width, height, wall, base):
    """A square tumbler (the original SHOP-VRB2 "cuboid" glass5): a floor and four upright walls."""
    def build(s: float) -> Geometry:
        w, h = width * s, height * s
        visual, uv, parts = g.tray((w, w, h), wall * s, base * s, flare=0.0)
        z = h - GRIP_DEPTH
        # Across two opposite walls from above, and around the body from the side like a round glass.
        frames = [top_down((0.0, 0.0, z), k * math.pi / 2, w) for k in range(2)]
        return Geometry(visual, parts, frames + side_frames(w / 2, 0.5 * h), uv)
    return build


def _mug(outer, wall, base):
    def build(s: float) -> Geometry:
        pts = _scaled(outer, s)
        visual, uv, parts = g.container(pts, wall * s, base * s, sectors=10)
        r_top, h = pts[-1]
        z_low, z_high = 0.22 * h, 0.82 * h
        handle = g.handle(r_top - 0.004, z_low, z_high, 0.032 * s, 0.009 * s)
        visual = g.concatenate([visual, *handle])
        uv = None  # the handle has no lathe coordinates; renderers fall back to cylindrical ones
        frames = handle_frames(r_top - 0.004, z_low, z_high, 0.032 * s, 0.009 * s, h)
        # The rim away from the handle, for mugs whose handle faces away from the arm.
        frames += rim_frames(pts, wall * s, 10, skip=lambda a: abs(math.remainder(a, 2 * math.pi)) < 1.0)
        return Geometry(visual, [*parts, *handle], frames, uv)
    return build


MUG1 = [(0.040, 0.0), (0.040, 0.095)]  # straight
MUG2 = [(0.036, 0.0), (0.042, 0.10)]  # tapered
MUG3 = [(0.044, 0.0), (0.046, 0.08)]  # wide cappuccino mug


def _can(radius, height, neck):
    def build(s: float) -> Geometry:
        r, h = radius * s, height * s
        profile = [(0.0, 0.0), (r * 0.85, 0.0), (r, 0.008 * s), (r, h - 0.012 * s), (r * neck, h), (0.0, h)]
        visual, uv = g.revolve(profile, 40)
        parts = [g.disc_part(r * 0.85, r, 0.0, 0.008 * s, 24), g.disc_part(r, r, 0.008 * s, h - 0.012 * s, 24),
                 g.disc_part(r, r * neck, h - 0.012 * s, h, 24)]
        frames = cylinder_frames(r, h - 0.012 * s - GRIP_DEPTH / 2) + side_frames(r, 0.5 * h)
        return Geometry(visual, parts, frames, uv)
    return build


def _thermos(radius, body_h, cap_radius, cap_h):
    def build(s: float) -> Geometry:
        r, h, rc, hc = radius * s, body_h * s, cap_radius * s, cap_h * s
        profile = [(0.0, 0.0), (r * 0.95, 0.0), (r, 0.006), (r, h - 0.01 * s), (r * 0.85, h), (rc, h),
                   (rc, h + hc), (0.0, h + hc)]
        visual, uv = g.revolve(profile, 40)
        parts = [g.disc_part(r * 0.95, r, 0.0, h - 0.01 * s, 24), g.disc_part(r, r * 0.85, h - 0.01 * s, h, 24),
                 g.disc_part(rc, rc, h, h + hc, 24)]
        # By the cap from above (the body of a wide flask does not fit between every gripper's fingers), or
        # around the body from the side.
        frames = cylinder_frames(rc, h + hc - GRIP_DEPTH) + side_frames(r, 0.5 * h)
        return Geometry(visual, parts, frames, uv)
    return build


def _wine_glass(foot_r, stem_h, bowl_outer):
    def build(s: float) -> Geometry:
        fr, sh, stem_r = foot_r * s, stem_h * s, 0.0045 * s
        bowl = [(r * s, z * s + sh) for r, z in bowl_outer]
        visual_bowl, _, bowl_parts = g.container(bowl, 0.003 * s, 0.006 * s, sections=40, sectors=10)
        foot = g.disc_part(fr, fr * 0.9, 0.0, 0.006 * s, 24)
        stem = g.disc_part(stem_r, stem_r, 0.005 * s, sh + 0.002 * s, 12)
        parts = [foot, stem, *bowl_parts]
        visual = g.concatenate([foot, stem, visual_bowl])
        # Pinching the bowl's rim from above, or the stem from the side where the hand fits under the bowl.
        frames = rim_frames(bowl, 0.003 * s, 10)
        stem_z = max(sh * 0.5, STEM_GRIP_HEIGHT)
        if stem_z < sh - 0.012:
            frames += [side((0.0, 0.0, stem_z), k * math.pi / 4, 2 * stem_r) for k in range(8)]
        return Geometry(visual, parts, frames, None)
    return build


WINE1 = [(0.018, 0.0), (0.038, 0.03), (0.041, 0.06), (0.040, 0.10)]  # tulip bowl on an 8 cm stem, open enough for a finger
WINE2 = [(0.02, 0.0), (0.045, 0.025), (0.048, 0.05), (0.046, 0.07)]  # wide red-wine bowl on a 6 cm stem
# White-wine bowl on a 7 cm stem (the original SHOP-VRB2 wine_glass3).
WINE3 = [(0.017, 0.0), (0.036, 0.03), (0.039, 0.055), (0.038, 0.085)]


def _carrying(category: Category) -> Category:
    """``category`` with the hidden physical properties its objects carry: those the measuring primitives read of
    an object in the hand (friction: ``push``, centre of mass: ``balance``) for a pickupable category, and loose
    contents (``shake``) for a closed one among them. A food box is closed but not pickupable: none."""
    if not category.pickupable:
        return category
    carried = ("friction", "com_offset", "contents") if category.closed else ("friction", "com_offset")
    return dataclasses.replace(category, physical_properties=carried)


CATALOGUE: dict[str, Category] = {
    c.name: _carrying(c)
    for c in [
        Category(
            "baking tray",
            {"baking_tray1": ("flat", _rect_tray(0.33, 0.23, 0.025, 0.004, 0.004)),
             "baking_tray2": ("flat", _bowl([(0.12, 0.0), (0.125, 0.035)], 0.004, 0.004))},
            (Finish("metal", (350, 600), ("gray", "black", "metallic")), Finish("rubber", (150, 300), PAINTS)),
            grasp_type="rim", pickupable=False, stackable=False, stack_base=True,
            sizes=("medium-sized", "large")),
        Category(
            "bowl",
            {"bowl1": ("hemisphere", _bowl(BOWL1, 0.005, 0.006)),
             "bowl2": ("hemisphere", _bowl(BOWL2, 0.005, 0.006)),
             "bowl3": ("hemisphere", _bowl(BOWL3, 0.005, 0.006))},
            (Finish("ceramic", (300, 450), CERAMIC_COLOURS), Finish("glass", (300, 450), ("transparent",)),
             Finish("plastic", (60, 120), PAINTS), Finish("wooden", (120, 200), ("brown",)),
             Finish("metal", (120, 200), ("metallic",))),
            grasp_type="rim", pickupable=True, stackable=True, stack_base=True),
        Category(
            "chopping board",
            {"chopping_board1": ("cuboid", _board(0.30, 0.20, 0.018, 0.02)),
             "chopping_board2": ("irregularly shaped", _board(0.28, 0.20, 0.018, 0.03, tab=(0.08, 0.05))),
             "chopping_board3": ("cuboid", _board(0.36, 0.24, 0.015, 0.01))},
            (Finish("wooden", (550, 850), ("brown",)), Finish("plastic", (400, 650), (*PAINTS, "white"))),
            grasp_type="box", pickupable=False, stackable=False, stack_base=True,
            sizes=("medium-sized", "large"), mass_exponent=3.0),
        Category(
            "food box",
            {"food_box1": ("cylindrical", _tub(0.06, 0.09, 0.012)),
             "food_box2": ("cuboid", _box_container(0.17, 0.12, 0.07))},
            (Finish("plastic", (200, 500), PAINTS), Finish("glass", (500, 800), ("transparent",))),
            grasp_type="box", pickupable=False, stackable=False, stack_base=True, mass_exponent=3.0, closed=True),
        Category(
            "glass",
            {"glass1": ("cylindrical", _glass(GLASS1, 0.004, 0.008)),
             "glass2": ("cylindrical", _glass(GLASS2, 0.004, 0.008)),
             "glass3": ("cylindrical", _glass(GLASS3, 0.004, 0.01))},
            (Finish("glass", (180, 300), ("transparent",)), Finish("plastic", (40, 80), PAINTS)),
            grasp_type="cylinder", pickupable=True, stackable=True, stack_base=False,
            imported_variants={"glass4": ("cylindrical", _glass(GLASS4, 0.004, 0.008)),
                               "glass5": ("cuboid", _square_glass(0.07, 0.08, 0.004, 0.008))}),
        Category(
            "mug",
            {"mug1": ("cylindrical", _mug(MUG1, 0.005, 0.007)),
             "mug2": ("cylindrical", _mug(MUG2, 0.005, 0.007)),
             "mug3": ("cylindrical", _mug(MUG3, 0.005, 0.007))},
            (Finish("ceramic", (280, 380), CERAMIC_COLOURS), Finish("metal", (150, 250), ("metallic", "gray")),
             Finish("plastic", (100, 150), PAINTS)),
            grasp_type="handle", pickupable=True, stackable=True, stack_base=False),
        Category(
            "plate",
            {"plate1": ("flat", _plate(PLATE1, 0.004, 0.005)), "plate2": ("flat", _plate(PLATE2, 0.004, 0.005))},
            (Finish("ceramic", (450, 650), CERAMIC_COLOURS), Finish("plastic", (120, 200), PAINTS),
             Finish("glass", (400, 600), ("transparent",))),
            grasp_type="rim", pickupable=False, stackable=False, stack_base=True),
        Category(
            "soda can",
            {"soda_can": ("cylindrical", _can(0.033, 0.122, 0.82)),
             "soda_can2": ("cylindrical", _can(0.029, 0.146, 0.85))},
            (Finish("metal", (340, 390), (*PAINTS, "gray")),),
            grasp_type="cylinder", pickupable=True, stackable=True, stack_base=False,
            sizes=("medium-sized",), mass_exponent=3.0, closed=True),
        Category(
            "thermos",
            {"thermos1": ("cylindrical", _thermos(0.037, 0.20, 0.03, 0.05)),
             "thermos2": ("cylindrical", _thermos(0.045, 0.17, 0.031, 0.04))},
            (Finish("metal", (250, 400), (*PAINTS, "metallic", "black")), Finish("plastic", (150, 250), PAINTS)),
            grasp_type="cylinder", pickupable=True, stackable=False, stack_base=False, closed=True),
        Category(
            "wine glass",
            {"wine_glass1": ("irregularly shaped", _wine_glass(0.037, 0.08, WINE1)),
             "wine_glass2": ("irregularly shaped", _wine_glass(0.04, 0.06, WINE2))},
            (Finish("glass", (140, 220), ("transparent",)), Finish("plastic", (50, 90), PAINTS)),
            grasp_type="cylinder", pickupable=True, stackable=False, stack_base=False,
            imported_variants={"wine_glass3": ("irregularly shaped", _wine_glass(0.036, 0.07, WINE3))}),
    ]
}


class ShopVrb2Objects(CatalogueObjectSet):
    """The ten SHOP-VRB2 categories with realistic sizes, weights, materials and contact stiffness."""

    set_name = "shopvrb2"
    catalogue = CATALOGUE

    def spec_from_scene_object(self, obj: SceneObject) -> ObjectSpec:
        """The spec that builds a scene object, from this project's files or the original SHOP-VRB2 ones
        (original model names, scale factors and shape words mapped: ``muble_plugins.objects.original``)."""
        return original.spec_from_scene_object(obj, self.catalogue, self.set_name,
                                               lambda spec: float(max(built_geometry(self, spec).extents[:2])))

    def rgba(self, spec: ObjectSpec) -> tuple[float, ...]:
        """An object of the original release's files is drawn in that release's paint colours
        (``original.ORIGINAL_PAINTS``); every other in the catalogue's."""
        return original.original_rgba(spec) or super().rgba(spec)

    def shape(self, category: Category, spec: ObjectSpec) -> Callable[[], Geometry]:
        """An object of the original release's files is built with that release's model, measured
        (``muble_plugins.objects.original_models``); every other spec with its catalogue model."""
        fit = original.original_fit(spec)
        if fit is None:
            return super().shape(category, spec)
        model, scale_factor = fit
        if model not in ORIGINAL_GEOMETRY:
            raise ConfigError(unknown_name("original SHOP-VRB2 model", model, sorted(ORIGINAL_GEOMETRY)))
        return lambda: ORIGINAL_GEOMETRY[model](scale_factor)

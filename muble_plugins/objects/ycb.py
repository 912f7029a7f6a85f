"""A YCB-like object set: nine items of the YCB benchmark approximated procedurally at published size and mass.

Dimensions (mm) and masses (g) are those published with the YCB object and model set (Calli et al., 2015):
cracker box 60×158×210, 411 g; sugar box 38×89×175, 514 g; tomato soup can ⌀66×101, 349 g; mustard bottle
50×85×175, 603 g; potted meat can 50×97×82, 370 g; bleach cleanser 250×98×65, 1131 g; bowl ⌀159×53, 147 g;
mug ⌀80×82, 118 g; foam brick 50×75×50, 28 g. Items come in one size and one finish each, so sampling only
varies the item. Cardboard boxes use the "plastic" material class, the nearest one renderers know.
"""
from __future__ import annotations

import math

import numpy as np

from muble_plugins.objects import geometry as g
from muble_plugins.objects.catalogue import Category, CatalogueObjectSet, Finish, Geometry, top_down
from muble_plugins.objects.shopvrb2 import _bowl, _can, _mug


def _box(sx, sy, sz, corner=0.004):
    def build(s: float) -> Geometry:
        visual, uv = g.rounded_box((sx * s, sy * s, sz * s), corner * s)
        narrow = min(sx, sy) * s
        yaw = 0.0 if sx <= sy else math.pi / 2  # fingers close across the narrow side
        return Geometry(visual, [visual], [top_down((0.0, 0.0, sz * s - 0.03), yaw + math.pi / 2, narrow)], uv)
    return build


def _bottle(sx, sy, body_h, neck_r, neck_h):
    def build(s: float) -> Geometry:
        body, _ = g.rounded_box((sx * s, sy * s, body_h * s), 0.45 * min(sx, sy) * s, segments=8)
        top = body.vertices[body.vertices[:, 2] > body_h * s - 1e-6]
        z_neck = (body_h + 0.02) * s
        neck = g.disc_part(neck_r * s, neck_r * s, z_neck, z_neck + neck_h * s, 16)
        shoulder = g.hull(np.concatenate([top, neck.vertices[neck.vertices[:, 2] < z_neck + 1e-6]]))
        parts = [body, shoulder, neck]
        narrow = min(sx, sy) * s
        yaw = math.pi / 2 if sx <= sy else 0.0
        return Geometry(g.concatenate(parts), parts, [top_down((0.0, 0.0, body_h * s * 0.7), yaw, narrow)], None)
    return build


def _one(name, model, shape, build, material, grams, colour, grasp, stackable=False, base=False):
    return Category(name, {model: (shape, build)}, (Finish(material, (grams, grams), (colour,)),),
                    grasp_type=grasp, pickupable=True, stackable=stackable, stack_base=base,
                    sizes=("medium-sized",))


CATALOGUE: dict[str, Category] = {
    c.name: c
    for c in [
        _one("cracker box", "003_cracker_box", "cuboid", _box(0.06, 0.158, 0.21), "plastic", 411, "red", "box",
             base=True),
        _one("sugar box", "004_sugar_box", "cuboid", _box(0.038, 0.089, 0.175), "plastic", 514, "yellow", "box"),
        _one("tomato soup can", "005_tomato_soup_can", "cylindrical", _can(0.033, 0.101, 0.9), "metal", 349,
             "red", "cylinder", stackable=True),
        _one("mustard bottle", "006_mustard_bottle", "irregularly shaped", _bottle(0.05, 0.085, 0.14, 0.012,
             0.015), "plastic", 603, "yellow", "box"),
        _one("potted meat can", "010_potted_meat_can", "cuboid", _box(0.05, 0.097, 0.082, 0.01), "metal", 370,
             "blue", "box", stackable=True),
        _one("bleach cleanser", "021_bleach_cleanser", "irregularly shaped", _bottle(0.065, 0.098, 0.21, 0.014,
             0.02), "plastic", 1131, "white", "box"),
        _one("bowl", "024_bowl", "hemisphere", _bowl([(0.03, 0.0), (0.055, 0.01), (0.075, 0.035),
                                                     (0.0795, 0.053)], 0.003, 0.004), "plastic", 147, "red",
             "rim", stackable=True, base=True),
        _one("mug", "025_mug", "cylindrical", _mug([(0.037, 0.0), (0.04, 0.082)], 0.004, 0.005), "plastic", 118,
             "red", "handle", stackable=True),
        _one("foam brick", "061_foam_brick", "cuboid", _box(0.05, 0.075, 0.05, 0.003), "rubber", 28, "red", "box",
             stackable=True),
    ]
}


class YcbObjects(CatalogueObjectSet):
    """YCB-like household items with their published dimensions and masses."""

    set_name = "ycb"
    catalogue = CATALOGUE

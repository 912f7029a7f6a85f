"""Procedural materials, one recipe per material class, built from shader nodes (no image textures).

Every recipe takes the object's base colour, so a red plastic and a red rubber differ only in how they
reflect light: sheen, roughness, transmission, grain. Materials are cached by (class, colour) within a scene.
"""
from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np

from muble.core.errors import unknown_name
from muble.core.objects import MATERIAL_CLASSES

log = logging.getLogger(__name__)

# SHOP-VRB2 material words that map onto a class under another name.
MATERIAL_ALIASES = {"wooden": "wood", "metallic": "metal", "porcelain": "ceramic", "steel": "metal",
                    "aluminium": "metal", "aluminum": "metal", "rubbery": "rubber"}


def material_class(word: str | None) -> str:
    """The material class for a scene object's ``material`` word; unknown words fall back to plastic."""
    if not word:
        return "plastic"
    word = word.lower()
    word = MATERIAL_ALIASES.get(word, word)
    if word in MATERIAL_CLASSES:
        return word
    log.warning("%s; drawing it as plastic", unknown_name("material", word, MATERIAL_CLASSES))
    return "plastic"


def _principled(mat: Any) -> Any:
    for node in mat.node_tree.nodes:
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            return node
    raise LookupError("new material has no Principled BSDF")


def _set(node: Any, **inputs: Any) -> None:
    for key, value in inputs.items():
        node.inputs[key.replace("_", " ")].default_value = value


def _object_coords(nodes: Any, links: Any) -> Any:
    coords = nodes.new("ShaderNodeTexCoord")
    return coords.outputs["Object"]


def _bump(nodes: Any, links: Any, bsdf: Any, height: Any, strength: float, distance: float) -> None:
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = strength
    bump.inputs["Distance"].default_value = distance
    links.new(height, bump.inputs["Height"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])


def _plastic(mat, bsdf, rgb, nodes, links):
    _set(bsdf, Base_Color=(*rgb, 1), Roughness=0.2, Specular_IOR_Level=0.5, IOR=1.46)


def _painted(mat, bsdf, rgb, nodes, links):
    _set(bsdf, Base_Color=(*rgb, 1), Roughness=0.45, Specular_IOR_Level=0.4)


def _rubber(mat, bsdf, rgb, nodes, links):
    # Matte, dark-ish, with a fine pebbled surface that breaks up the highlights.
    _set(bsdf, Base_Color=(*(0.7 * np.asarray(rgb)), 1), Roughness=0.9, Specular_IOR_Level=0.15,
         Sheen_Weight=0.3, Sheen_Roughness=0.6)
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 400.0
    links.new(_object_coords(nodes, links), noise.inputs["Vector"])
    _bump(nodes, links, bsdf, noise.outputs["Fac"], 0.25, 0.002)


def _metal(mat, bsdf, rgb, nodes, links):
    # Brushed metal: anisotropic highlights and roughness streaks stretched along the object's z axis.
    tint = 0.35 + 0.65 * np.asarray(rgb)
    _set(bsdf, Base_Color=(*tint, 1), Metallic=1.0, Anisotropic=0.6)
    coords = _object_coords(nodes, links)
    stretch = nodes.new("ShaderNodeMapping")
    stretch.inputs["Scale"].default_value = (300.0, 300.0, 4.0)
    links.new(coords, stretch.inputs["Vector"])
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 1.0
    links.new(stretch.outputs["Vector"], noise.inputs["Vector"])
    ramp = nodes.new("ShaderNodeMapRange")
    ramp.inputs["To Min"].default_value = 0.12
    ramp.inputs["To Max"].default_value = 0.3
    links.new(noise.outputs["Fac"], ramp.inputs["Value"])
    links.new(ramp.outputs["Result"], bsdf.inputs["Roughness"])


def _glass(mat, bsdf, rgb, nodes, links):
    # Clear glass with a light tint of the object's colour.
    tint = 0.6 + 0.4 * np.asarray(rgb)
    _set(bsdf, Base_Color=(*tint, 1), Roughness=0.02, IOR=1.5, Transmission_Weight=1.0)


def _ceramic(mat, bsdf, rgb, nodes, links):
    # Glazed: a diffuse body under a sharp clear coat, with a touch of subsurface light.
    _set(bsdf, Base_Color=(*rgb, 1), Roughness=0.4, Coat_Weight=1.0, Coat_Roughness=0.03, Coat_IOR=1.5,
         Subsurface_Weight=0.1, Subsurface_Scale=0.01)


def _wood(mat, bsdf, rgb, nodes, links, rings: float | None = None):
    # Objects: the grain is distorted bands across the object's bounding box, pulled between a dark and a light
    # tone of the colour, with a faint bump; box-relative coordinates keep its size in proportion to the object,
    # so that it reads on a small bowl. ``rings`` (per metre) asks for the boards' straight grain instead (the
    # table).
    if rings is not None:
        _boards(bsdf, rgb, nodes, links, rings)
        return
    coords = nodes.new("ShaderNodeTexCoord").outputs["Generated"]
    wave = nodes.new("ShaderNodeTexWave")
    wave.wave_type = "BANDS"
    wave.bands_direction = "X"
    wave.inputs["Scale"].default_value = 3.0  # bands across the bounding box
    wave.inputs["Distortion"].default_value = 9.0
    wave.inputs["Detail"].default_value = 4.0
    wave.inputs["Detail Scale"].default_value = 1.2
    links.new(coords, wave.inputs["Vector"])
    ramp = nodes.new("ShaderNodeValToRGB")
    rgb = np.asarray(rgb)
    ramp.color_ramp.elements[0].color = (*(0.3 * rgb), 1)
    ramp.color_ramp.elements[1].color = (*np.clip(1.15 * rgb, 0, 1), 1)
    links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    _set(bsdf, Roughness=0.55, Specular_IOR_Level=0.35)
    _bump(nodes, links, bsdf, wave.outputs["Fac"], 0.05, 0.001)


def _boards(bsdf, rgb, nodes, links, rings: float) -> None:
    # Flat-sawn boards, as the original's desk: growth rings are bands running along the object's x axis (the
    # table's depth, away from the camera), wandering slowly along it, each a light early-wood band ending in a
    # thin dark late-wood line; fine fibres are noise stretched along the same axis. Object coordinates are
    # metres: ``rings`` per metre across the grain.
    coords = _object_coords(nodes, links)
    along = nodes.new("ShaderNodeMapping")  # compress x: every feature is long along the grain
    along.inputs["Scale"].default_value = (0.06, 1.0, 1.0)
    links.new(coords, along.inputs["Vector"])
    wave = nodes.new("ShaderNodeTexWave")
    wave.wave_type = "BANDS"
    wave.bands_direction = "Y"
    wave.wave_profile = "SAW"  # a ring's early wood fades into its sharp late-wood line
    wave.inputs["Scale"].default_value = rings * math.pi / 10  # a BANDS period is 2 pi / (20 scale)
    wave.inputs["Distortion"].default_value = 12.0
    wave.inputs["Detail"].default_value = 2.0
    wave.inputs["Detail Scale"].default_value = 0.6
    links.new(along.outputs["Vector"], wave.inputs["Vector"])
    fibre_map = nodes.new("ShaderNodeMapping")
    fibre_map.inputs["Scale"].default_value = (4.0, 350.0, 350.0)
    links.new(coords, fibre_map.inputs["Vector"])
    fibres = nodes.new("ShaderNodeTexNoise")
    fibres.inputs["Scale"].default_value = 1.0
    fibres.inputs["Detail"].default_value = 3.0
    links.new(fibre_map.outputs["Vector"], fibres.inputs["Vector"])
    mix = nodes.new("ShaderNodeMix")  # float mix: 55 % rings, 45 % fibres
    mix.data_type = "FLOAT"
    mix.inputs["Factor"].default_value = 0.45
    links.new(wave.outputs["Fac"], mix.inputs["A"])
    links.new(fibres.outputs["Fac"], mix.inputs["B"])
    ramp = nodes.new("ShaderNodeValToRGB")
    rgb = np.asarray(rgb)
    ramp.color_ramp.elements[0].position = 0.3
    ramp.color_ramp.elements[0].color = (*np.clip(1.05 * rgb, 0, 1), 1)  # early wood, light
    ramp.color_ramp.elements[1].position = 0.85
    ramp.color_ramp.elements[1].color = (*(0.72 * rgb), 1)  # late wood, dark
    links.new(mix.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    # A thin satin varnish: soft reflections of what stands on the table.
    _set(bsdf, Roughness=0.45, Specular_IOR_Level=0.5, Coat_Weight=0.35, Coat_Roughness=0.2, Coat_IOR=1.5)
    _bump(nodes, links, bsdf, fibres.outputs["Fac"], 0.08, 0.0005)


RECIPES = {"plastic": _plastic, "metal": _metal, "glass": _glass, "rubber": _rubber, "wood": _wood,
           "ceramic": _ceramic, "painted": _painted}


class MaterialLibrary:
    """Builds and caches the materials of one scene; ``clear`` removes them from Blender."""

    def __init__(self) -> None:
        self._cache: dict[tuple, Any] = {}

    def get(self, cls: str, rgba: np.ndarray | tuple[float, ...], **details: float) -> Any:
        """The material of class ``cls`` in colour ``rgba``; ``details`` are recipe options (wood: ``rings``,
        growth rings per metre of a board's straight grain)."""
        import bpy

        if cls not in RECIPES:
            from muble.core.errors import ConfigError

            raise ConfigError(unknown_name("material class", cls, tuple(RECIPES)))
        rgb = tuple(round(float(c), 3) for c in np.asarray(rgba, dtype=float)[:3])
        key = (cls, rgb, tuple(sorted(details.items())))
        if key not in self._cache:
            mat = bpy.data.materials.new(f"muble_{cls}_{len(self._cache)}")
            bsdf = _principled(mat)
            RECIPES[cls](mat, bsdf, _srgb_to_linear(np.asarray(rgb)), mat.node_tree.nodes, mat.node_tree.links,
                         **details)
            self._cache[key] = mat
        return self._cache[key]

    def clear(self) -> None:
        import bpy

        for mat in self._cache.values():
            bpy.data.materials.remove(mat)
        self._cache.clear()


def _srgb_to_linear(rgb: np.ndarray) -> tuple[float, float, float]:
    """MuJoCo colours are display (sRGB) values; Blender shades in linear light."""
    rgb = np.clip(rgb, 0.0, 1.0)
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return tuple(float(c) for c in lin)

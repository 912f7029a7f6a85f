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


def _bump(nodes: Any, links: Any, shaders: Any, height: Any, strength: float, distance: float) -> None:
    """Bump ``height`` onto the normal of a shader node (or of each of a list of them)."""
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = strength
    bump.inputs["Distance"].default_value = distance
    links.new(height, bump.inputs["Height"])
    for shader in shaders if isinstance(shaders, list) else [shaders]:
        links.new(bump.outputs["Normal"], shader.inputs["Normal"])


def _surface(nodes: Any, links: Any, bsdf: Any, shader: Any) -> None:
    """Make ``shader`` the material's surface in place of its Principled BSDF."""
    output = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    links.new(shader, output.inputs["Surface"])
    nodes.remove(bsdf)


def _bsdf(nodes: Any, kind: str, colour: Any, roughness: float | None = None, **options: Any) -> Any:
    """A Diffuse (``diffuse``), Glossy (``glossy``) or Sheen (``sheen``) BSDF; ``colour`` a linear RGB or a
    colour socket to link. Options: ``distribution``, ``anisotropy``."""
    node = nodes.new({"diffuse": "ShaderNodeBsdfDiffuse", "glossy": "ShaderNodeBsdfAnisotropic",
                      "sheen": "ShaderNodeBsdfSheen"}[kind])
    if "distribution" in options:
        node.distribution = options["distribution"]
    if "anisotropy" in options:
        node.inputs["Anisotropy"].default_value = options["anisotropy"]
    if roughness is not None:
        node.inputs["Roughness"].default_value = roughness
    if isinstance(colour, (tuple, list, np.ndarray)):
        node.inputs["Color"].default_value = (*colour, 1)
    else:
        node.id_data.links.new(colour, node.inputs["Color"])
    return node.outputs[0]


def _mixed(nodes: Any, links: Any, factor: Any, first: Any, second: Any) -> Any:
    """``first`` where ``factor`` is 0, ``second`` where it is 1: a number or a socket to link."""
    mix = nodes.new("ShaderNodeMixShader")
    if isinstance(factor, (int, float)):
        mix.inputs["Fac"].default_value = factor
    else:
        links.new(factor, mix.inputs["Fac"])
    links.new(first, mix.inputs[1])
    links.new(second, mix.inputs[2])
    return mix.outputs["Shader"]


def multiplied_colour(nodes: Any, links: Any, rgb: Any, factor: float, by: Any) -> Any:
    """The linear RGB colour ``rgb`` multiplied by the socket ``by``, blended in by ``factor`` (a Mix node's
    Result: ``rgb * (1 - factor + factor * by)``)."""
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = factor
    mix.inputs["A"].default_value = (*rgb, 1)
    links.new(by, mix.inputs["B"])
    return mix.outputs["Result"]


def _facing(nodes: Any, blend: float) -> Any:
    weight = nodes.new("ShaderNodeLayerWeight")
    weight.inputs["Blend"].default_value = blend
    return weight.outputs["Fresnel"]


# The material classes below are the original release's own (its Blender material and model files, MIT: the
# shaders they mix, their colours, roughnesses and weights), so that the objects look as in its frames.


def _plastic(mat, bsdf, rgb, nodes, links):
    # A diffuse body under two clear glossy layers that take over towards grazing angles (layer-weight Fresnel
    # of blend 0.3 and 0.5): the colour stays saturated where the surface faces the camera and greys at its rims.
    # The body and the first layer are gently wavy (a faint bump of slow noise, 3 per metre).
    diffuse = _bsdf(nodes, "diffuse", rgb)
    glaze = _bsdf(nodes, "glossy", (0.745,) * 3, 0.1, distribution="GGX")
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    noise.inputs["Detail"].default_value = 1.0
    links.new(_object_coords(nodes, links), noise.inputs["Vector"])
    _bump(nodes, links, [diffuse.node, glaze.node], noise.outputs["Fac"], 0.05, 4.04)
    body = _mixed(nodes, links, _facing(nodes, 0.3), diffuse, glaze)
    _surface(nodes, links, bsdf, _mixed(nodes, links, _facing(nodes, 0.5), body,
                                        _bsdf(nodes, "glossy", (0.631,) * 3, 0.1, distribution="BECKMANN")))


def _painted(mat, bsdf, rgb, nodes, links):
    _set(bsdf, Base_Color=(*rgb, 1), Roughness=0.45, Specular_IOR_Level=0.4)


def _rubber(mat, bsdf, rgb, nodes, links):
    # Matte: the colour darkened in large patches (times 0.5 + 0.5 d^2, d the distance to the nearest cell point
    # of a Voronoi pattern of 0.35 cells per metre), a diffuse body with a velvet sheen towards the rims, and a
    # broad glossy layer by the Fresnel of IOR 1.519.
    cells = nodes.new("ShaderNodeTexVoronoi")
    cells.inputs["Scale"].default_value = 0.35
    links.new(_object_coords(nodes, links), cells.inputs["Vector"])
    squared = nodes.new("ShaderNodeMath")
    squared.operation = "MULTIPLY"
    links.new(cells.outputs["Distance"], squared.inputs[0])
    links.new(cells.outputs["Distance"], squared.inputs[1])
    colour = multiplied_colour(nodes, links, rgb, 0.5, squared.outputs["Value"])
    fresnel = nodes.new("ShaderNodeFresnel")
    fresnel.inputs["IOR"].default_value = 1.519
    body = _mixed(nodes, links, fresnel.outputs["Fac"], _bsdf(nodes, "diffuse", colour),
                  _bsdf(nodes, "sheen", colour, 0.6))
    _surface(nodes, links, bsdf, _mixed(nodes, links, fresnel.outputs["Fac"], body,
                                        _bsdf(nodes, "glossy", colour, 0.592, distribution="BECKMANN")))


def _metal(mat, bsdf, rgb, nodes, links):
    # Coloured metal: the paint colour itself is the reflectance (a red thermos stays red rather than turning
    # pink under a whitened tint); 40 % a broad (roughness 0.447) and 60 % a sharp (0.1) glossy lobe, both
    # slightly anisotropic.
    _surface(nodes, links, bsdf, _mixed(nodes, links, 0.6, _bsdf(nodes, "glossy", rgb, 0.447, anisotropy=0.25),
                                        _bsdf(nodes, "glossy", rgb, 0.1, anisotropy=0.25)))


def _glass(mat, bsdf, rgb, nodes, links):
    # Clear glass (IOR 1.45, as the original's, whose glass passes 98 %) with a faint tint of the object's colour:
    # a light passes four walls of a tumbler, so a stronger tint per wall greys the glass. Thin walls: the models
    # are solid, and refraction through a solid base showed the table under it, in the glass's own shadow, as a
    # black pool. Refractive caustics are off (noise), so shadow rays pass through instead, in the tint.
    tint = 1.0 - 0.15 * (1.0 - np.asarray(rgb))
    _set(bsdf, Base_Color=(*tint, 1), Roughness=0.02, IOR=1.45, Transmission_Weight=1.0)
    output = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    clear = nodes.new("ShaderNodeBsdfTransparent")
    clear.inputs["Color"].default_value = (*np.clip(0.9 * tint, 0, 1), 1)
    mix = nodes.new("ShaderNodeMixShader")
    links.new(nodes.new("ShaderNodeLightPath").outputs["Is Shadow Ray"], mix.inputs["Fac"])
    links.new(bsdf.outputs["BSDF"], mix.inputs[1])
    links.new(clear.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], output.inputs["Surface"])


def _ceramic(mat, bsdf, rgb, nodes, links):
    # Glazed: 88 % diffuse body, 12 % a light grey glossy lobe of roughness 0.5.
    _surface(nodes, links, bsdf, _mixed(nodes, links, 0.12, _bsdf(nodes, "diffuse", rgb),
                                        _bsdf(nodes, "glossy", (0.8,) * 3, 0.5, distribution="GGX")))


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


# The desk's grain: growth rings per metre of the second, finer set of rings (the first is ``rings``); where in its
# period a ring's dark late-wood line starts (it ends with the period), and how dark the line is against the
# early wood. Measured on the original's frames: thin dark lines, unevenly about 4-8 mm apart, on a light body.
FINE_RINGS = 1.63
LATE_WOOD_START = 0.8
LATE_WOOD_TONE = 0.55


def _saw_rings(nodes, links, vector, scale: float, distortion: float, offset: float) -> Any:
    """A thin line at the end of each period of slowly wandering bands along the object's x axis (0..1)."""
    shift = nodes.new("ShaderNodeMapping")
    shift.inputs["Location"].default_value = (0.0, offset, offset)
    links.new(vector, shift.inputs["Vector"])
    wave = nodes.new("ShaderNodeTexWave")
    wave.wave_type = "BANDS"
    wave.bands_direction = "Y"
    wave.wave_profile = "SAW"
    wave.inputs["Scale"].default_value = scale * math.pi / 10  # a BANDS period is 2 pi / (20 scale)
    wave.inputs["Distortion"].default_value = distortion
    wave.inputs["Detail"].default_value = 2.0
    wave.inputs["Detail Scale"].default_value = 0.6
    links.new(shift.outputs["Vector"], wave.inputs["Vector"])
    line = nodes.new("ShaderNodeMapRange")
    line.inputs["From Min"].default_value = LATE_WOOD_START
    line.inputs["From Max"].default_value = 1.0
    links.new(wave.outputs["Fac"], line.inputs["Value"])
    return line.outputs["Result"]


def _boards(bsdf, rgb, nodes, links, rings: float) -> None:
    # Flat-sawn oak boards, as the original's desk: growth rings run along the object's x axis (the table's depth,
    # away from the camera) and wander slowly along it. Each ring is a light early-wood body ending in a thin dark
    # late-wood line; two sets of rings at unrelated spacings make the lines irregular, not a regular ridge
    # pattern, and fine fibres stretched along the grain break them up. Object coordinates are metres: ``rings``
    # per metre across the grain. Under a glossy varnish that mirrors what stands on the table.
    coords = _object_coords(nodes, links)
    along = nodes.new("ShaderNodeMapping")  # compress x: every feature is long along the grain
    along.inputs["Scale"].default_value = (0.06, 1.0, 1.0)
    links.new(coords, along.inputs["Vector"])
    coarse = _saw_rings(nodes, links, along.outputs["Vector"], rings, 10.0, 0.0)
    fine = _saw_rings(nodes, links, along.outputs["Vector"], rings * FINE_RINGS, 14.0, 3.7)
    weaker = nodes.new("ShaderNodeMath")
    weaker.operation = "MULTIPLY"
    weaker.inputs[1].default_value = 0.7
    links.new(fine, weaker.inputs[0])
    late = nodes.new("ShaderNodeMath")
    late.operation = "MAXIMUM"
    links.new(coarse, late.inputs[0])
    links.new(weaker.outputs["Value"], late.inputs[1])
    fibre_map = nodes.new("ShaderNodeMapping")
    fibre_map.inputs["Scale"].default_value = (4.0, 350.0, 350.0)
    links.new(coords, fibre_map.inputs["Vector"])
    fibres = nodes.new("ShaderNodeTexNoise")
    fibres.inputs["Scale"].default_value = 1.0
    fibres.inputs["Detail"].default_value = 3.0
    links.new(fibre_map.outputs["Vector"], fibres.inputs["Vector"])
    mix = nodes.new("ShaderNodeMix")  # float mix: 80 % late-wood lines, 20 % fibres
    mix.data_type = "FLOAT"
    mix.inputs["Factor"].default_value = 0.2
    links.new(late.outputs["Value"], mix.inputs["A"])
    links.new(fibres.outputs["Fac"], mix.inputs["B"])
    ramp = nodes.new("ShaderNodeValToRGB")
    rgb = np.asarray(rgb)
    ramp.color_ramp.elements[0].position = 0.1
    ramp.color_ramp.elements[0].color = (*rgb, 1)  # early wood
    ramp.color_ramp.elements[1].position = 0.8
    ramp.color_ramp.elements[1].color = (*(LATE_WOOD_TONE * rgb), 1)  # late wood
    links.new(mix.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    _set(bsdf, Roughness=0.5, Specular_IOR_Level=0.5, Coat_Weight=1.0, Coat_Roughness=0.08, Coat_IOR=1.5)
    _bump(nodes, links, bsdf, fibres.outputs["Fac"], 0.05, 0.0005)


RECIPES = {"plastic": _plastic, "metal": _metal, "glass": _glass, "rubber": _rubber, "wood": _wood,
           "ceramic": _ceramic, "painted": _painted}


class MaterialLibrary:
    """Builds and caches the materials of one scene; ``clear`` removes them from Blender."""

    def __init__(self) -> None:
        self._cache: dict[tuple, Any] = {}

    def get(self, cls: str, rgba: np.ndarray | tuple[float, ...], *, linear: bool = False, **details: float) -> Any:
        """The material of class ``cls`` in colour ``rgba``; ``details`` are recipe options (wood: ``rings``,
        growth rings per metre of a board's straight grain). A colour is a display (sRGB) value, decoded to the
        linear reflectance Blender shades with, unless ``linear``: then it is that reflectance already."""
        import bpy

        if cls not in RECIPES:
            from muble.core.errors import ConfigError

            raise ConfigError(unknown_name("material class", cls, tuple(RECIPES)))
        rgb = tuple(round(float(c), 3) for c in np.asarray(rgba, dtype=float)[:3])
        key = (cls, rgb, linear, tuple(sorted(details.items())))
        if key not in self._cache:
            mat = bpy.data.materials.new(f"muble_{cls}_{len(self._cache)}")
            bsdf = _principled(mat)
            reflectance = rgb if linear else _srgb_to_linear(np.asarray(rgb))
            RECIPES[cls](mat, bsdf, reflectance, mat.node_tree.nodes, mat.node_tree.links, **details)
            self._cache[key] = mat
        return self._cache[key]

    def clear(self) -> None:
        import bpy

        for mat in self._cache.values():
            bpy.data.materials.remove(mat)
        self._cache.clear()


def _srgb_to_linear(rgb: np.ndarray) -> tuple[float, ...]:
    """MuJoCo colours are display (sRGB) values; Blender shades in linear light (one value per channel)."""
    rgb = np.clip(rgb, 0.0, 1.0)
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return tuple(float(c) for c in lin)

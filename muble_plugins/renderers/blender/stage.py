"""The stage around the models: render engine settings, the light rig and the world background."""
from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np

from muble.core.errors import ConfigError, RenderError, unknown_name

from .config import BACKDROPS, COLOUR_SPACES, DENOISER_QUALITIES, DEVICES, ENGINES, BlenderRendererConfig
from .materials import multiplied_colour

log = logging.getLogger(__name__)

GPU_BACKENDS = ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL")

# Key, fill and back light: azimuth and elevation (degrees) around the scene centre, distance in scene radii,
# power (W per square metre of distance) and size in scene radii. The camera usually looks from +x.
LIGHT_RIG = (
    ("key", 35.0, 50.0, 2.5, 1.5, 0.8),
    ("fill", -50.0, 30.0, 2.5, 0.5, 1.2),
    ("back", 180.0, 60.0, 2.5, 1.0, 0.6),
)


def check_config(cfg: BlenderRendererConfig) -> None:
    """Reject option values Blender would silently misread (the schema's bounds are checked where it is built)."""
    if cfg.engine not in ENGINES:
        raise ConfigError(unknown_name("render engine", cfg.engine, ENGINES))
    if cfg.device not in DEVICES:
        raise ConfigError(unknown_name("render device", cfg.device, DEVICES))
    if cfg.object_colours not in COLOUR_SPACES:
        raise ConfigError(unknown_name("object colour space", cfg.object_colours, COLOUR_SPACES))
    if cfg.backdrop not in BACKDROPS:
        raise ConfigError(unknown_name("backdrop", cfg.backdrop, BACKDROPS))
    if cfg.denoiser_quality not in DENOISER_QUALITIES:
        raise ConfigError(unknown_name("denoiser quality", cfg.denoiser_quality, DENOISER_QUALITIES))
    if cfg.engine == "BLENDER_EEVEE" and cfg.segmentation:
        raise ConfigError("EEVEE has no object-index pass for segmentation; use engine=CYCLES or "
                          "segmentation=false")


def _enable_gpu(device: str) -> bool:
    """Turn on the first GPU backend Cycles finds; False when there is none."""
    import bpy

    prefs = bpy.context.preferences.addons["cycles"].preferences
    for backend in GPU_BACKENDS:
        try:
            prefs.compute_device_type = backend
        except TypeError:  # backend not compiled into this build
            continue
        prefs.get_devices()
        gpus = [d for d in prefs.devices if d.type == backend]
        if gpus:
            for d in prefs.devices:
                d.use = d.type == backend
            log.info("Cycles renders on %s: %s", backend, ", ".join(d.name for d in gpus))
            return True
    if device == "GPU":
        raise RenderError("device=GPU but Cycles found no CUDA/OptiX/HIP/oneAPI/Metal device; use device=CPU")
    return False


def configure_engine(scene: Any, cfg: BlenderRendererConfig) -> None:
    """Engine, resolution, sampling, denoising, colour management and the pass file format."""
    import bpy  # noqa: F401  (scene is a bpy.types.Scene)

    render = scene.render
    render.engine = cfg.engine
    render.resolution_x, render.resolution_y = cfg.width, cfg.height
    render.resolution_percentage = 100
    render.threads_mode = "FIXED" if cfg.threads > 0 else "AUTO"
    if cfg.threads > 0:
        render.threads = cfg.threads
    render.use_persistent_data = True  # keep the BVH and shaders between keyframes of one scene
    render.film_transparent = False
    # The pass file: every pass of the render in one uncompressed float EXR (see exr.py).
    settings = render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"  # Blender 5: multilayer EXR is offered only under this media type
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "NONE"
    render.use_file_extension = True
    # Standard view transform: the combined pass is turned into sRGB with exactly this transform in numpy.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    if cfg.engine == "CYCLES":
        cycles = scene.cycles
        gpu = cfg.device != "CPU" and _enable_gpu(cfg.device)
        cycles.device = "GPU" if gpu else "CPU"
        cycles.samples = cfg.samples
        cycles.use_adaptive_sampling = cfg.adaptive_sampling
        cycles.adaptive_threshold = cfg.adaptive_threshold
        cycles.use_denoising = cfg.denoise
        if cfg.denoise:
            cycles.denoiser = "OPENIMAGEDENOISE"
            cycles.denoising_quality = cfg.denoiser_quality
            cycles.denoising_prefilter = "FAST" if cfg.denoiser_quality == "FAST" else "ACCURATE"
            cycles.denoising_input_passes = "RGB_ALBEDO"
        cycles.max_bounces = cfg.max_bounces
        cycles.diffuse_bounces = min(cfg.max_bounces, cfg.diffuse_bounces)
        cycles.glossy_bounces = min(cfg.max_bounces, cfg.glossy_bounces)
        cycles.transmission_bounces = cfg.transmission_bounces
        cycles.transparent_max_bounces = cfg.transparent_bounces
        # A glass bowl is four surfaces deep: its refracted paths need their own budget past max_bounces.
        cycles.max_bounces = max(cfg.max_bounces, cfg.transmission_bounces)
        cycles.caustics_reflective = False
        cycles.caustics_refractive = False
        cycles.use_fast_gi = cfg.fast_gi
        cycles.use_light_tree = False  # three lights: the tree costs more than it saves (measured)
        cycles.blur_glossy = 1.0  # filter glossy paths: less fireflies at few samples
        cycles.seed = cfg.seed
    else:
        scene.eevee.taa_render_samples = cfg.samples


def set_passes(view_layer: Any, depth: bool, segmentation: bool, normals: bool) -> None:
    view_layer.use_pass_combined = True
    view_layer.use_pass_z = depth
    view_layer.use_pass_object_index = segmentation
    view_layer.use_pass_normal = normals


# The original MuBlE frames show their studio's backdrop (a lit, curved sweep behind the table) as a light warm grey
# that brightens towards the horizon: seen from the scene file's camera, its linear luminance is about
# 0.4286 + 0.0674 x + 0.0504 y - 0.2154 z for a view direction (x, y, z) (least squares over the backdrop pixels of
# the five reference frames, RMS 0.03), in the tint below. Camera, glossy and transmission rays see it; diffuse
# light keeps coming from the uniform sky.
STUDIO_LUMINANCE = (0.4286, (0.0674, 0.0504, -0.2154))  # (constant, per view-direction component), linear
STUDIO_TINT = (1.027, 0.997, 0.951)  # linear RGB over luminance: slightly warm
WORLD_MAP_RESOLUTION = 64  # width of the world's importance map (Cycles' own choice is 1024 for any non-uniform one)


def build_world(cfg: BlenderRendererConfig) -> Any:
    """The world: a uniform sky colour (soft ambient light) and, with ``backdrop: studio``, the original's studio
    backdrop behind the stage where a camera ray hits nothing; with ``backdrop: sky`` the camera sees the sky."""
    import bpy

    world = bpy.data.worlds.new("muble_world")
    if world.node_tree is None:  # worlds made by Python have no node tree before 5.0
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    sky = next(n for n in nodes if n.bl_idname == "ShaderNodeBackground")
    sky.inputs["Color"].default_value = (*cfg.background_rgb, 1.0)
    sky.inputs["Strength"].default_value = cfg.background_strength
    if cfg.backdrop == "studio":
        _studio_backdrop(nodes, links, sky)
        # The backdrop varies smoothly and lights nothing diffusely (the sky does): a coarse importance map of the
        # world is enough, where Cycles would otherwise build a 1024-wide one for any non-uniform world.
        world.cycles.sampling_method = "MANUAL"
        world.cycles.sample_map_resolution = WORLD_MAP_RESOLUTION
    return world


def _studio_backdrop(nodes: Any, links: Any, sky: Any) -> None:
    output = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputWorld")
    direction = nodes.new("ShaderNodeTexCoord").outputs["Generated"]  # a world's: the ray's direction
    slope = nodes.new("ShaderNodeVectorMath")
    slope.operation = "DOT_PRODUCT"
    slope.inputs[1].default_value = STUDIO_LUMINANCE[1]
    links.new(direction, slope.inputs[0])
    level = nodes.new("ShaderNodeMath")
    level.operation = "ADD"
    level.use_clamp = True
    level.inputs[1].default_value = STUDIO_LUMINANCE[0]
    links.new(slope.outputs["Value"], level.inputs[0])
    tint = multiplied_colour(nodes, links, STUDIO_TINT, 1.0, level.outputs["Value"])
    backdrop = nodes.new("ShaderNodeBackground")
    backdrop.inputs["Strength"].default_value = 1.0
    links.new(tint, backdrop.inputs["Color"])
    # Seen directly, reflected or through glass: the backdrop; diffuse light still comes from the sky.
    path = nodes.new("ShaderNodeLightPath")
    seen = nodes.new("ShaderNodeMath")
    seen.operation = "MAXIMUM"
    # A reflection sees the sweep only in front (towards -x, where it stands); behind the camera the studio is
    # open, so a mirror-like thermos reflects the dim sky there, not a second backdrop.
    ahead = nodes.new("ShaderNodeSeparateXYZ")
    links.new(direction, ahead.inputs["Vector"])
    forward = nodes.new("ShaderNodeMapRange")
    forward.inputs["From Min"].default_value, forward.inputs["From Max"].default_value = 0.0, -0.25
    links.new(ahead.outputs["X"], forward.inputs["Value"])
    reflected = nodes.new("ShaderNodeMath")
    reflected.operation = "MULTIPLY"
    links.new(path.outputs["Is Glossy Ray"], reflected.inputs[0])
    links.new(forward.outputs["Result"], reflected.inputs[1])
    links.new(path.outputs["Is Camera Ray"], seen.inputs[0])
    links.new(reflected.outputs["Value"], seen.inputs[1])
    seen_through = nodes.new("ShaderNodeMath")
    seen_through.operation = "MAXIMUM"
    links.new(seen.outputs["Value"], seen_through.inputs[0])
    links.new(path.outputs["Is Transmission Ray"], seen_through.inputs[1])
    mix = nodes.new("ShaderNodeMixShader")
    links.new(seen_through.outputs["Value"], mix.inputs["Fac"])
    links.new(sky.outputs["Background"], mix.inputs[1])
    links.new(backdrop.outputs["Background"], mix.inputs[2])
    links.new(mix.outputs["Shader"], output.inputs["Surface"])


# SHOP-VRB2 scene files carry the original's three lamps in ``lamp_params`` (name -> position); the role is read
# from the name. Power is the irradiance at the aim point (W per square metre of distance), size in metres.
LAMP_ROLES = {"key": (4.0, 0.8), "fill": (1.5, 1.2), "back": (2.5, 0.6)}
# The lamps' colours in the original's Blender files (the studio lamps its material and shape files carry, under
# the same names): a warm key, a cool fill, a white back light.
LAMP_COLOURS = {"key": (1.0, 0.932, 0.817), "fill": (0.762, 0.818, 1.0), "back": (1.0, 1.0, 1.0)}


def _lamp_role(name: str) -> str | None:
    lowered = name.lower()
    return next((role for role in LAMP_ROLES if role in lowered), None)


def _area_light(collection: Any, name: str, location: Any, target: Any, power: float, size: float,
                colour: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> Any:
    import bpy
    from mathutils import Vector

    data = bpy.data.lights.new(f"muble_{name}", type="AREA")
    data.shape = "DISK"
    data.size = size
    data.color = colour
    # Power scales with distance squared so the irradiance at the target does not depend on the distance.
    data.energy = power * (Vector(location) - Vector(target)).length ** 2
    light = bpy.data.objects.new(f"muble_{name}", data)
    light.location = Vector(location)
    light.rotation_euler = (Vector(target) - light.location).to_track_quat("-Z", "Y").to_euler()
    collection.objects.link(light)
    return light


def build_scene_lamps(collection: Any, lamps: dict[str, Any], target: np.ndarray,
                      cfg: BlenderRendererConfig, energy: dict[str, float] | None = None) -> list[Any]:
    """The scene file's key, fill and back lamps where it placed them, aimed at ``target``; no jitter (the
    generator decides where lamps go, and ``energy``, the scene's ``lamp_energy``, how much brighter or dimmer
    than its role's power each one is). Lamps whose name names no role are lit like a fill."""
    lights = []
    for name, position in sorted(lamps.items()):
        if not isinstance(position, (list, tuple)) or len(position) != 3:
            continue
        role = _lamp_role(name) or "fill"
        power, size = LAMP_ROLES[role]
        factor = float((energy or {}).get(name, 1.0))
        lights.append(_area_light(collection, str(name).lower(), np.asarray(position, dtype=float), target,
                                  power * cfg.light_energy * factor, size, LAMP_COLOURS[role]))
    return lights


def build_lights(collection: Any, centre: np.ndarray, radius: float, cfg: BlenderRendererConfig,
                 rng: np.random.Generator) -> list[Any]:
    """Key, fill and back area lights aimed at the scene centre, jittered in position and power (scenes
    without ``lamp_params``)."""
    import bpy
    from mathutils import Vector

    lights = []
    for name, azimuth, elevation, distance, power, size in LIGHT_RIG:
        jitter = cfg.light_jitter
        az = math.radians(azimuth + 30.0 * jitter * rng.uniform(-1, 1))
        el = math.radians(np.clip(elevation + 20.0 * jitter * rng.uniform(-1, 1), 5.0, 89.0))
        dist = distance * radius * (1.0 + jitter * rng.uniform(-1, 1))
        data = bpy.data.lights.new(f"muble_{name}", type="AREA")
        data.shape = "DISK"
        data.size = size * radius
        # Power scales with distance squared so the irradiance at the centre does not depend on scene size.
        data.energy = power * dist**2 * cfg.light_energy * (1.0 + jitter * rng.uniform(-1, 1))
        light = bpy.data.objects.new(f"muble_{name}", data)
        light.location = Vector(centre) + dist * Vector((math.cos(el) * math.cos(az),
                                                         math.cos(el) * math.sin(az), math.sin(el)))
        direction = Vector(centre) - light.location
        light.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
        collection.objects.link(light)
        lights.append(light)
    return lights

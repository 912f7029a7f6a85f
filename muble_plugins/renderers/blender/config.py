"""Options of the Blender renderer; the Hydra schema of ``muble_conf/renderer/blender.yaml``."""
from __future__ import annotations

from dataclasses import dataclass, field

from muble import bounded
from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH

ENGINES = ("CYCLES", "BLENDER_EEVEE")
DEVICES = ("CPU", "GPU", "auto")
DENOISER_QUALITIES = ("FAST", "BALANCED", "HIGH")
BACKDROPS = ("studio", "sky")
COLOUR_SPACES = ("linear", "srgb")


@dataclass
class BlenderRendererConfig:
    """Quality, passes and scene dressing of the Blender renderer.

    The defaults are the cheapest setting ``benchmarks/render_quality.py`` measured within SSIM 0.95 (worst 0.92)
    and 40 dB PSNR of a converged reference (1024 samples, 16 bounces, no denoising): 8 Cycles samples with
    adaptive sampling, 8 bounces of every kind, no fast GI, the high-quality OpenImageDenoise preset.
    """

    width: int = bounded(DEFAULT_WIDTH, ge=1)  # the SHOP-VRB2 camera's image, as the MuJoCo renderer: masks line up
    height: int = bounded(DEFAULT_HEIGHT, ge=1)
    engine: str = "CYCLES"  # CYCLES or BLENDER_EEVEE (EEVEE wants a GPU or a display)
    device: str = "CPU"  # CPU, GPU (CUDA/OptiX/HIP/oneAPI/Metal, first found) or auto (GPU if any)
    samples: int = bounded(8, ge=1)
    adaptive_sampling: bool = True
    adaptive_threshold: float = 0.05
    denoise: bool = True
    denoiser_quality: str = "HIGH"  # OpenImageDenoise quality: FAST, BALANCED, HIGH
    max_bounces: int = 8
    transmission_bounces: int = 8  # glass: in and out of both walls of a bowl, and the table seen through it
    transparent_bounces: int = 8
    diffuse_bounces: int = 8  # each capped by max_bounces
    glossy_bounces: int = 8
    fast_gi: bool = False  # approximate indirect light past the first bounce (faster, biased: darker)
    threads: int = bounded(0, ge=0)  # 0 = all cores
    # Ground-truth passes, read from the same render as the RGB.
    depth: bool = True
    segmentation: bool = True
    normals: bool = False
    # Scene dressing.
    # MuJoCo geom groups drawn: robosuite puts visual geoms in group 1, MuBlE's objects theirs in group 2.
    geom_groups: list[int] = field(default_factory=lambda: [1, 2])
    floor: bool = True  # draw the world body's floor
    # Draw robosuite's room (the arena's walls). Off by default: the scene lamps stand where the original's stood,
    # outside that room, and the walls turn the lit table into a box of bounced light (noisy, slow to converge).
    walls: bool = False
    # How an object's MuJoCo colour becomes its reflectance: ``linear`` takes the values as linear reflectance, as the
    # original SHOP-VRB2 generator put its colours into Blender (its objects look lighter than the same colour
    # shown as sRGB); ``srgb`` decodes them as the display colours MuJoCo shows.
    object_colours: str = "linear"
    table_material: str = "wood"
    # The original's light oak under its varnish and lamps: the mean colour of its desk in the reference frames.
    table_rgb: list[float] | None = field(default_factory=lambda: [0.715, 0.56, 0.365])  # None: MuJoCo's colour
    # What the camera sees where nothing is hit: the original's studio backdrop, a light grey brightening towards
    # the horizon (``studio``), or the sky colour (``sky``). Either way the sky lights the scene.
    backdrop: str = "studio"
    background_rgb: list[float] = field(default_factory=lambda: [0.78, 0.80, 0.84])
    background_strength: float = 0.3
    light_energy: float = 1.0  # multiplies the key/fill/back rig
    light_jitter: float = 0.1  # relative jitter of light position and energy, drawn per scene from ``seed``
    seed: int = 0
    exposure: float = 0.0  # stops; with the scene lamps: mean pixel ~120 of 255, 99th percentile ~210

"""Options of the Blender renderer; the Hydra schema of ``muble_conf/renderer/blender.yaml``."""
from __future__ import annotations

from dataclasses import dataclass, field

from muble import bounded

ENGINES = ("CYCLES", "BLENDER_EEVEE")
DEVICES = ("CPU", "GPU", "auto")
DENOISER_QUALITIES = ("FAST", "BALANCED", "HIGH")


@dataclass
class BlenderRendererConfig:
    """Quality, passes and scene dressing of the Blender renderer.

    The defaults are the speed/quality point measured by ``benchmarks/render.py`` for about 2 s per 640×480
    keyframe on 2 CPU cores: 4 Cycles samples with adaptive sampling, the fast OpenImageDenoise preset and
    Cycles' fast GI approximation for indirect light.
    """

    width: int = bounded(848, ge=1)  # the SHOP-VRB2 camera's image, as the MuJoCo renderer: masks line up
    height: int = bounded(480, ge=1)
    engine: str = "CYCLES"  # CYCLES or BLENDER_EEVEE (EEVEE wants a GPU or a display)
    device: str = "CPU"  # CPU, GPU (CUDA/OptiX/HIP/oneAPI/Metal, first found) or auto (GPU if any)
    samples: int = bounded(4, ge=1)
    adaptive_sampling: bool = True
    adaptive_threshold: float = 0.05
    denoise: bool = True
    denoiser_quality: str = "FAST"  # OpenImageDenoise quality: FAST, BALANCED, HIGH
    max_bounces: int = 2
    transmission_bounces: int = 8  # glass: in and out of both walls of a bowl, and the table seen through it
    transparent_bounces: int = 8
    diffuse_bounces: int = 2  # each capped by max_bounces
    glossy_bounces: int = 2
    fast_gi: bool = True  # approximate indirect light past the first bounce (ambient-occlusion style)
    threads: int = bounded(0, ge=0)  # 0 = all cores
    # Ground-truth passes, read from the same render as the RGB.
    depth: bool = True
    segmentation: bool = True
    normals: bool = False
    # Scene dressing.
    # MuJoCo geom groups drawn: robosuite puts visual geoms in group 1, MuBlE's objects theirs in group 2.
    geom_groups: list[int] = field(default_factory=lambda: [1, 2])
    floor: bool = True  # draw the world body's geoms (floor, walls)
    table_material: str = "wood"
    table_rgb: list[float] | None = field(default_factory=lambda: [0.62, 0.45, 0.3])  # None: MuJoCo's colour
    background_rgb: list[float] = field(default_factory=lambda: [0.78, 0.80, 0.84])
    background_strength: float = 0.3
    light_energy: float = 1.0  # multiplies the key/fill/back rig
    light_jitter: float = 0.1  # relative jitter of light position and energy, drawn per scene from ``seed``
    seed: int = 0
    exposure: float = 1.0  # stops; with the scene lamps, frames sit mid-range without clipping highlights

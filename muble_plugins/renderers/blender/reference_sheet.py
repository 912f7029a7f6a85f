"""Renders the reference contact sheet of the docs: the six material classes side by side, then keyframes
of a tabletop episode (the arm moving over randomly placed objects).

    python -m muble_plugins.renderers.blender.reference_sheet docs/images/blender_reference.png
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


def render_sheet(path: Path, width: int = 640, height: int = 480, samples: int = 16, keyframes: int = 5) -> None:
    import mujoco
    from PIL import Image

    from muble.io.image_grid import contact_sheet
    from muble_plugins.renderers.render_world import build_world, material_rig, random_scene, world_rng

    from .renderer import BlenderRenderer

    images, captions = [], []
    renderer = BlenderRenderer(width=width, height=height, samples=samples)
    try:
        scene, model, data = material_rig(fovy=64.0)  # the whole row fits a 4:3 frame
        renderer.setup(scene, model)
        images.append(renderer.render(data, "materials").rgb)
        captions.append("plastic metal glass rubber wood ceramic")
        scene = random_scene(world_rng(7), n_objects=5)
        model, data = build_world(scene, arm_seed=7)
        renderer.setup(scene, model)
        start = data.qpos[:7].copy()
        for k in range(keyframes):
            data.qpos[:7] = start + 0.25 * np.sin(np.arange(7) * 1.3 + k * 0.8)
            mujoco.mj_forward(model, data)
            images.append(renderer.render(data, "frontview" if k % 2 == 0 else "agentview").rgb)
            captions.append(f"keyframe {k}")
    finally:
        renderer.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(contact_sheet(images, columns=3, width=400, labels=captions)).save(path)
    log.info("wrote %s", path)


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    render_sheet(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images/blender_reference.png"))

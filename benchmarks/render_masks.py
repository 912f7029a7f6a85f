"""Blender and MuJoCo masks of generated SHOP-VRB2 scenes, both renderers at their defaults' frame geometry.

Each scene comes from the scene generator (as ``muble generate`` makes it), is built by the environment and
seen through the scene's camera (``front``) by both renderers at the same resolution, 848x480 unless scaled.
Blender's segmentation is its object-index pass; masks need few samples, so Blender renders 1 sample without
denoising. For every object (and the robot and table) that MuJoCo shows with at least ``MIN_PIXELS`` pixels, the
IoU of the two masks is reported; the goal is IoU >= 0.9 for every object of every scene.

    python benchmarks/render_masks.py [SCENES] [SCALE] [OVERRIDE ...]   # defaults: 20 scenes, scale 1.0 (848x480)

Hydra overrides after the counts compose the run (``generator.stage=original``: scenes generated on that stage).
"""
from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

MIN_PIXELS = 30
GOAL = 0.9


def scene_ious(blender, mujoco_renderer, env, scene) -> dict[str, float]:
    """IoU per label name (``object <id>``, ``robot``, ``table``) of one scene's front camera."""
    from muble import SEG_ROBOT, SEG_TABLE

    camera = env.names.cameras.get("front", "front")
    graph = env.sync_scene_graph()
    blender.setup(graph, env.model)
    mujoco_renderer.setup(graph, env.model)
    ours = blender.render(env.data, camera).segmentation
    ref = mujoco_renderer.render(env.data, camera).segmentation
    out = {}
    for label in [SEG_ROBOT, SEG_TABLE, *scene.ids]:
        reference = ref == label
        if reference.sum() < MIN_PIXELS:
            continue
        mask = ours == label
        name = "robot" if label == SEG_ROBOT else "table" if label == SEG_TABLE else f"object {label}"
        out[name] = float((mask & reference).sum() / (mask | reference).sum())
    return out


def main() -> int:
    from omegaconf import OmegaConf

    from muble import get_registry
    from muble.app.config import compose
    from muble.episode.components import build_components, scene_generator
    from muble.sim.build import object_models
    from muble.sim.env import TabletopEnv
    from muble.stage.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH
    from muble_plugins.renderers.blender import BlenderRenderer

    scenes = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    scale = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
    width, height = round(DEFAULT_WIDTH * scale), round(DEFAULT_HEIGHT * scale)
    start = time.perf_counter()
    overrides = sys.argv[3:]
    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp", *overrides])
    components = build_components(cfg, renderer=False, task=False)
    robot = OmegaConf.to_container(cfg.robot, resolve=True)
    blender = BlenderRenderer(width=width, height=height, samples=1, denoise=False)
    mujoco_renderer = get_registry().create("renderer", "mujoco", {"width": width, "height": height})
    generator = scene_generator(cfg, components["object_set"])
    per_scene, worst = [], []
    try:
        for index in range(scenes):
            scene = generator.generate(index)
            env = TabletopEnv(scene, object_models(scene, components["object_set"], cfg.objects.name), robot, {})
            try:
                ious = scene_ious(blender, mujoco_renderer, env, scene)
            finally:
                env.close()
            per_scene.append(ious)
            worst += [(round(v, 4), index, k) for k, v in ious.items()]
            print(f"scene {index}: " + ", ".join(f"{k} {v:.3f}" for k, v in ious.items()), flush=True)
    finally:
        generator.close()
        blender.close()
        mujoco_renderer.close()
    objects = [v for s in per_scene for k, v in s.items() if k.startswith("object")]
    value = min(objects) if objects else float("nan")
    print(json.dumps({
        "benchmark": "render_masks", "metric": "minimum object-mask IoU, Blender vs MuJoCo, generated scenes",
        "value": round(value, 4), "unit": "IoU", "goal": GOAL, "scenes": scenes, "resolution": [width, height],
        "objects_scored": len(objects), "median_object_iou": round(float(np.median(objects)), 4) if objects else None,
        "robot_min": round(min(s["robot"] for s in per_scene if "robot" in s), 4),
        "table_min": round(min(s["table"] for s in per_scene if "table" in s), 4),
        "worst(iou,scene,label)": sorted(worst)[:3], "blender": {"samples": 1, "denoise": False},
        "overrides": overrides,
        "seconds": round(time.perf_counter() - start, 1),
    }))
    return 0 if objects and value >= GOAL else 1


if __name__ == "__main__":
    sys.exit(main())

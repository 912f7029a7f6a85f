"""Memory of a long Blender rendering process: RSS growth over 200 keyframes across 20 scenes.

Three warm-up scenes come first (Blender and Cycles allocate their caches, the allocator its arenas: about 160 MB
measured); growth is measured from the end of the warm-up to the end of the last measured scene. Run: ``python benchmarks/render_memory.py``.
"""
from __future__ import annotations

import json
import os
import sys
import time

import mujoco
import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from muble_plugins.renderers.blender import BlenderRenderer  # noqa: E402
from muble_plugins.renderers.render_world import build_world, random_scene, world_rng  # noqa: E402

SCENES, KEYFRAMES, WARM_UP = 20, 10, 3


def rss_mb() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise OSError("no VmRSS in /proc/self/status")


def main() -> int:
    start = time.perf_counter()
    renderer = BlenderRenderer(width=96, height=72, samples=1, denoise=False)
    samples, warm = [], 0.0
    for index in range(WARM_UP + SCENES):
        scene = random_scene(world_rng(index), n_objects=3 + index % 4, image_index=index)
        model, data = build_world(scene, arm_seed=index)
        renderer.setup(scene, model)
        for k in range(KEYFRAMES):
            data.qpos[:7] += 0.05 * np.sin(np.arange(7) + k)
            mujoco.mj_forward(model, data)
            renderer.render(data, "frontview")
        if index == WARM_UP - 1:
            warm = rss_mb()
        elif index >= WARM_UP:
            samples.append(rss_mb())
    renderer.close()
    growth = samples[-1] - warm
    print(json.dumps({
        "benchmark": "render_memory", "metric": "RSS growth over 200 keyframes in 20 scenes (after warm-up)",
        "value": round(growth, 1), "unit": "MB", "goal": 50.0, "keyframes": SCENES * KEYFRAMES,
        "rss_after_warm_up_mb": round(warm, 1), "peak_growth_mb": round(max(samples) - warm, 1),
        "rss_after_each_scene_mb": [round(s, 1) for s in samples], "seconds": round(time.perf_counter() - start, 1),
    }))
    return 0 if growth <= 50.0 else 1


if __name__ == "__main__":
    sys.exit(main())

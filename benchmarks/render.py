"""Blender keyframe cost: first-frame build, seconds per 640x480 keyframe, and the cost of the GT passes.

Run from the repository root: ``python benchmarks/render.py``. The baseline (RGB only: no depth and no
segmentation pass) is measured in the same run, on the same scene, in blocks interleaved with the
with-passes renders so that load changes on a shared machine hit both alike.
"""
from __future__ import annotations

import json
import logging
import os
import statistics
import sys
import time

import mujoco
import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from muble_plugins.renderers.blender import BlenderRenderer  # noqa: E402
from muble_plugins.renderers.render_world import build_world, random_scene, world_rng  # noqa: E402

CAMERA = "frontview"
BLOCK = 2  # keyframes per block; blocks go passes, RGB only, passes, RGB only


CPU_SECONDS: dict[bool, list[float]] = {True: [], False: []}  # process CPU time (all threads), by passes on/off


def keyframe(renderer: BlenderRenderer, model, data, step: int) -> float:
    data.qpos[:7] += 0.03 * np.sin(np.arange(7) + step)  # the arm moves between keyframes
    mujoco.mj_forward(model, data)
    start, cpu = time.perf_counter(), time.process_time()
    renderer.render(data, CAMERA)
    CPU_SECONDS[renderer.config.segmentation].append(time.process_time() - cpu)
    return time.perf_counter() - start


def main() -> int:
    logging.basicConfig(level=logging.WARNING)
    scene = random_scene(world_rng(0), n_objects=5)
    model, data = build_world(scene, arm_seed=0)
    renderer = BlenderRenderer()  # the default quality
    cfg = renderer.config
    start = time.perf_counter()
    renderer.setup(scene, model)
    build_s = time.perf_counter() - start
    first_s = keyframe(renderer, model, data, 0)
    with_passes, rgb_only, step = [], [], 1
    for block in range(4):
        passes = block % 2 == 0
        renderer.configure_passes(depth=passes, segmentation=passes)
        renderer.render(data, CAMERA)  # the first render after a pass change rebuilds the film; not timed
        for _ in range(BLOCK):
            (with_passes if passes else rgb_only).append(keyframe(renderer, model, data, step))
            step += 1
    renderer.close()
    per_keyframe = statistics.median(with_passes)
    baseline = statistics.median(rgb_only)
    overhead = (per_keyframe - baseline) / baseline
    print(f"setup {build_s:.2f} s, first keyframe {first_s:.2f} s, keyframe with passes {per_keyframe:.2f} s, "
          f"RGB only {baseline:.2f} s, passes overhead {100 * overhead:+.1f} %", file=sys.stderr)
    print(json.dumps({
        "benchmark": "render", "metric": "seconds per 640x480 keyframe after the first (with GT passes)",
        "value": round(per_keyframe, 3), "unit": "s", "goal": 2.0,
        "first_frame_build_s": round(build_s + first_s, 3), "setup_s": round(build_s, 3),
        "first_render_s": round(first_s, 3), "rgb_only_s": round(baseline, 3),
        "cpu_s_per_keyframe": round(statistics.median(CPU_SECONDS[True][1:]), 3),
        "cpu_s_rgb_only": round(statistics.median(CPU_SECONDS[False]), 3),
        "passes_overhead_cpu_fraction": round(statistics.median(CPU_SECONDS[True][1:])
                                              / statistics.median(CPU_SECONDS[False]) - 1, 4),
        "note": "wall times on a shared machine; cpu_s_per_keyframe / cores is the time on idle cores",
        "passes_overhead_fraction": round(overhead, 4), "passes_overhead_goal": 0.10,
        "with_passes_all_s": [round(t, 3) for t in with_passes], "rgb_only_all_s": [round(t, 3) for t in rgb_only],
        "settings": {"width": cfg.width, "height": cfg.height, "engine": cfg.engine, "device": cfg.device,
                     "samples": cfg.samples, "adaptive_sampling": cfg.adaptive_sampling,
                     "adaptive_threshold": cfg.adaptive_threshold, "denoise": cfg.denoise,
                     "denoiser_quality": cfg.denoiser_quality, "max_bounces": cfg.max_bounces,
                     "cpu_cores": os.cpu_count(), "geoms": int(model.ngeom)},
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())

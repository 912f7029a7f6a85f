"""Blender vs MuJoCo on the same states: segmentation IoU per object, robot and table, and depth error.

Acceptance of the Blender renderer over 20 scenes (two cameras each): IoU >= 0.9 for every object and the
robot, median depth error on object pixels <= 1 cm. Run: ``python benchmarks/render_sync.py``.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support: helpers shared with the tests

from muble import SEG_ROBOT, SEG_TABLE  # noqa: E402
from muble_plugins.renderers.blender import BlenderRenderer  # noqa: E402
from muble_plugins.renderers.blender.labels import geom_labels  # noqa: E402
from muble_plugins.renderers.render_world import build_world, random_scene, world_rng  # noqa: E402
from tests.support.render_check import mask_iou, mujoco_reference  # noqa: E402

SCENES, WIDTH, HEIGHT = 20, 320, 240
CAMERAS = ("frontview", "agentview")
MIN_PIXELS = 30  # a label needs this many pixels in MuJoCo's view to be scored


def main() -> int:
    start = time.perf_counter()
    renderer = BlenderRenderer(width=WIDTH, height=HEIGHT, samples=1, denoise=False)
    ious: dict[str, list[float]] = {"object": [], "robot": [], "table": []}
    depth_errors, worst_cases = [], []
    for index in range(SCENES):
        scene = random_scene(world_rng(1000 + index), n_objects=3 + index % 4, image_index=index)
        model, data = build_world(scene, arm_seed=index)
        renderer.setup(scene, model)
        labels = geom_labels(model, scene)
        for camera in CAMERAS:
            frame = renderer.render(data, camera)
            ref_seg, ref_depth = mujoco_reference(model, data, camera, WIDTH, HEIGHT, labels)
            for label in [SEG_ROBOT, SEG_TABLE, *scene.ids]:
                if (ref_seg == label).sum() < MIN_PIXELS:
                    continue
                kind = "robot" if label == SEG_ROBOT else "table" if label == SEG_TABLE else "object"
                iou = mask_iou(frame.segmentation == label, ref_seg == label)
                ious[kind].append(iou)
                worst_cases.append((round(iou, 4), index, camera, label, int((ref_seg == label).sum()),
                                    int((frame.segmentation == label).sum())))
            on_objects = ref_seg >= 0
            depth_errors.append(float(np.median(np.abs(frame.depth - ref_depth)[on_objects])))
    renderer.close()
    worst = min(min(v) for v in ious.values())
    summary = {kind: {"n": len(v), "min": round(min(v), 4), "median": round(float(np.median(v)), 4)}
               for kind, v in ious.items()}
    print(json.dumps({
        "benchmark": "render_sync", "metric": "minimum segmentation IoU Blender vs MuJoCo (objects, robot, table)",
        "value": round(worst, 4), "unit": "IoU", "goal": 0.9, "scenes": SCENES, "cameras": list(CAMERAS),
        "resolution": [WIDTH, HEIGHT], "iou": summary,
        "depth_median_abs_error_m": {"max_over_views": round(max(depth_errors), 6),
                                     "median": round(float(np.median(depth_errors)), 6), "goal": 0.01},
        "worst_cases(iou,scene,camera,label,mujoco_px,blender_px)": sorted(worst_cases)[:3],
        "seconds": round(time.perf_counter() - start, 1),
    }))
    return 0 if worst >= 0.9 and max(depth_errors) <= 0.01 else 1


if __name__ == "__main__":
    sys.exit(main())

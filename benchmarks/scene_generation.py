"""Scene generation speed: valid scenes per second on one core, with the occlusion check, with and without the
stability check. ``--validate N`` also generates N scenes with every check and re-verifies the acceptance rules
(mesh clearance, visibility, rest, weight gaps) from the written scene graphs.

    python benchmarks/scene_generation.py [--scenes 30] [--validate 0]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("MUJOCO_GL", "egl")
# The figure is per core: Mesa's software rasteriser would otherwise draw with one thread per CPU.
os.environ.setdefault("LP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from muble.generation import SceneGenerator  # noqa: E402
from muble.generation.checks import settle  # noqa: E402
from muble.generation.contact_sheet import models_from_scene, placements_from_scene  # noqa: E402
from muble.generation.ground_truth import decode_mask  # noqa: E402
from muble.generation.placement import CollisionMesh, min_pairwise_distance  # noqa: E402
from muble_conf import group_defaults  # noqa: E402


def rate(generator: SceneGenerator, start: int, count: int) -> dict:
    generator.timings.clear()
    t0 = time.perf_counter()
    for i in range(start, start + count):
        generator.generate(i)
    elapsed = time.perf_counter() - t0
    stages = {k: round(v / count * 1e3, 1) for k, v in sorted(generator.timings.items())}
    return {"scenes_per_s": count / elapsed, "ms_per_scene": elapsed / count * 1e3, "stage_ms": stages}


def validate(generator: SceneGenerator, count: int) -> dict:
    cfg = generator.config
    worst = {"min_clearance_m": np.inf, "min_visible_px": np.inf, "max_settle_motion_m": 0.0, "min_weight_gap_g": np.inf}
    failures = 0
    for i in range(count):
        scene = generator.generate(10_000 + i)
        models = models_from_scene(generator.object_set, scene)
        placements = placements_from_scene(scene)
        clearance = min_pairwise_distance([CollisionMesh(m) for m in models], placements)
        visible = min(int(decode_mask(o.mask).sum()) for o in scene.objects)
        moved = float(settle(models, placements, cfg.table_x, cfg.table_y, cfg.timestep, 1.0).max())
        gap = float(np.diff(sorted(o.weight_gt for o in scene.objects)).min())
        ok = (clearance >= cfg.margin - 1e-9 and visible >= cfg.min_visible_pixels and moved <= 0.005
              and gap >= cfg.min_weight_gap)
        failures += not ok
        worst["min_clearance_m"] = min(worst["min_clearance_m"], clearance)
        worst["min_visible_px"] = min(worst["min_visible_px"], visible)
        worst["max_settle_motion_m"] = max(worst["max_settle_motion_m"], moved)
        worst["min_weight_gap_g"] = min(worst["min_weight_gap_g"], gap)
        if (i + 1) % 50 == 0:  # long validations report as they go
            print(json.dumps({"validated": i + 1, "invalid": failures, **worst}), file=sys.stderr, flush=True)
    return {"validated_scenes": count, "invalid_scenes": failures, **{k: float(v) for k, v in worst.items()}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=30, help="scenes timed per mode")
    parser.add_argument("--warmup", type=int, default=80, help="scenes generated first (fills mesh caches)")
    parser.add_argument("--validate", type=int, default=0, help="scenes re-verified against the acceptance rules")
    args = parser.parse_args()

    builtin = {**group_defaults("generator", "shopvrb2"), "object_set": "shopvrb2"}
    fast = SceneGenerator({**builtin, "stability": False}, seed=0)
    rate(fast, 0, args.warmup)
    without = rate(fast, 1_000, args.scenes)
    full = SceneGenerator({**builtin, "stability": True}, seed=0, object_set=fast.object_set, renderer=fast.renderer)
    with_stability = rate(full, 2_000, args.scenes)
    no_masks = SceneGenerator({**builtin, "stability": False, "masks": False, "occlusion_scale": 0.5}, seed=0,
                              object_set=fast.object_set)
    rate(no_masks, 0, 10)
    half_res = rate(no_masks, 3_000, args.scenes)
    report = {
        "benchmark": "scene_generation",
        "metric": "valid scenes per second per core, occlusion check, no stability check",
        "value": round(without["scenes_per_s"], 2),
        "unit": "scenes/s",
        "goal": 50,
        "without_stability": without,
        "with_stability": with_stability,
        "occlusion_half_res_no_masks": half_res,
        "rejections": dict(fast.failures + full.failures),
        "settings": {"scenes": args.scenes, "warmup": args.warmup, "image": [fast.camera.width, fast.camera.height],
                     "rasteriser_threads": os.environ.get("LP_NUM_THREADS")},
    }
    if args.validate:
        report["validation"] = validate(full, args.validate)
    fast.close()
    no_masks.close()
    print(json.dumps(report))


if __name__ == "__main__":
    main()

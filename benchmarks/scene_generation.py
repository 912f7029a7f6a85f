"""Scene generation speed: valid scenes per second on one core, with the occlusion check, with and without the
stability check. ``--validate N`` also generates N scenes with every check and re-verifies the acceptance rules
(mesh clearance, visibility, rest, weight gaps) from the written scene graphs. ``--dataset N`` profiles
``muble generate`` itself per stage on N indices of the val split, as one worker produces them (sequences and
MuJoCo keyframes, the defaults): seconds per stage, CPU seconds per scene and disk per scene, by file kind.

    python benchmarks/scene_generation.py [--scenes 30] [--validate 0] [--dataset 0 [--dataset-only]]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

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
        moved = float(settle(models, placements, cfg.table_x, cfg.table_y, generator.timestep, 1.0).max())
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


def file_kind(parts: tuple[str, ...]) -> str:
    """``("keyframes", stem, "frame_0001.png")`` -> ``keyframes/<episode>/*.png``; ``("keyframes",
    "x_states.npz")`` -> ``keyframes/*_states.npz``; ``("scenes", "x.json")`` -> ``scenes/*.json``."""
    name = parts[-1]
    tail = "_states.npz" if name.endswith("_states.npz") else "".join(Path(name).suffixes)
    return "/".join([parts[0], *["<episode>"] * (len(parts) > 2), f"*{tail}"])


def dataset_profile(count: int, overrides: list[str]) -> dict:
    """``produce_index`` on ``count`` val indices with the ``generate`` config (plus ``overrides``), after one
    index that fills the worker's caches: seconds per stage and CPU seconds per scene, and the files' size."""
    import collections
    import tempfile

    from omegaconf import OmegaConf

    from muble.app.config import compose
    from muble.dataset.production import IndexJob, produce_index

    with tempfile.TemporaryDirectory() as root:
        cfg = compose("generate", [f"dataset.root={root}", "output.dir=" + root, *overrides])
        config = OmegaConf.to_container(cfg, resolve=True)
        produce_index(IndexJob(config, "val", 10_000))  # warm-up: plugins, meshes, renderer, grip geometry
        warm = {str(p) for p in Path(root).rglob("*") if p.is_file()}
        stages: collections.Counter = collections.Counter()
        wall, cpu = [], []
        for index in range(count):
            t, c = time.perf_counter(), time.process_time()
            produce_index(IndexJob(config, "val", index), stages)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        sizes: collections.Counter = collections.Counter()
        for path in Path(root).rglob("*"):
            parts = path.relative_to(root).parts
            if path.is_file() and str(path) not in warm and len(parts) > 2:  # val/<folder>/…: one index's files
                sizes[file_kind(parts[1:])] += path.stat().st_size
    per_scene = {k: round(v / count, 3) for k, v in sorted(stages.items())}
    return {"scenes": count, "s_per_scene": round(sum(wall) / count, 2), "cpu_s_per_scene": round(sum(cpu) / count, 2),
            "stage_s_per_scene": per_scene, "unaccounted_s": round(sum(wall) / count - sum(per_scene.values()), 3),
            "disk_kb_per_scene": round(sum(sizes.values()) / count / 1024, 1),
            "disk_kb_per_scene_by_kind": {k: round(v / count / 1024, 1) for k, v in sorted(sizes.items())},
            "overrides": overrides}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=30, help="scenes timed per mode")
    parser.add_argument("--warmup", type=int, default=80, help="scenes generated first (fills mesh caches)")
    parser.add_argument("--validate", type=int, default=0, help="scenes re-verified against the acceptance rules")
    parser.add_argument("--dataset", type=int, default=0, help="indices of `muble generate` profiled per stage")
    parser.add_argument("--dataset-only", action="store_true", help="only the --dataset profile")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="generate config override for --dataset, repeatable")
    args = parser.parse_args()
    if args.dataset_only:
        profile = dataset_profile(args.dataset, args.overrides)
        print(json.dumps({"benchmark": "scene_generation", "metric": "muble generate CPU seconds per scene "
                          "(sequences, MuJoCo keyframes, one worker)", "value": profile["cpu_s_per_scene"],
                          "unit": "CPU-s", "goal": 15, "dataset": profile}))
        return

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
    if args.dataset:
        report["dataset"] = dataset_profile(args.dataset, args.overrides)
    fast.close()
    no_masks.close()
    print(json.dumps(report))


if __name__ == "__main__":
    main()

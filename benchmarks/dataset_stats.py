"""Task distribution of a generated SHOP-VRB2 split beside the paper's figures, without physics episodes.

Each index goes through what ``muble generate`` does before it runs the oracle with physics: the split's task
mix assigns its template and object count (``muble.generation.task_mix``), scene samples are drawn until one suits
the template (with the generator's visibility and rest checks, and with ``--reach-check`` the robot's grasp
check), an instruction is chosen and its ground truth rolled out by the symbolic oracle. Reported: template
shares (paper: 10% each, about 1,000/100/100 scenes per type), objects per scene (paper: 4 in 47.3%, 5 in
52.7%), words per instruction (paper: 5-16), ground-truth primitives per plan (paper: 5-46), scene samples drawn
per index, and the time per scene.

    python benchmarks/dataset_stats.py [--scenes 1000] [--split val] [--seed 0] [--workers 2] [--reach-check]

The metric is the largest deviation of a template's share from its target, in percentage points (goal: 2).
"""
from __future__ import annotations

import argparse
import collections
import json
import multiprocessing
import os
import time

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

PAPER = {"template_share": 0.10, "objects": {"4": 0.473, "5": 0.527}, "words": [5, 16], "plan_primitives": [5, 46]}
GOAL_POINTS = 2.0


def _worker(args: tuple) -> list[dict]:
    seed, split, indices, reach, templates, weights = args
    from muble.app.config import compose
    from muble.app.run import scene_generator
    from muble.dataset.production import split_seed
    from muble.episode.runner import instruction_rng
    from muble.generation.task_mix import suited_scene
    from muble.plugins.registry import get_registry

    s = split_seed(seed, split)
    cfg = compose("generate", [f"seed={s}", "output.dir=/tmp", "dataset.root=/tmp/unused",
                               f"generator.reach_check={str(reach).lower()}", f"generator.split={split}"])
    registry = get_registry()
    generator = scene_generator(cfg, registry.create("object_set", cfg.objects.name, cfg.objects))
    tasks = {t: registry.create("task", t, {}) for t in templates}
    out = []
    try:
        for index in indices:
            start = time.perf_counter()
            suited = suited_scene(generator, tasks, weights, s, index, lambda i: instruction_rng(s, i))
            out.append({"index": index, "template": suited.template, "objects": len(suited.scene.objects),
                        "words": len(suited.instruction.instruction.split()), "plan": len(suited.ground_truth),
                        "samples": suited.samples, "layouts": 1 + sum(suited.rejections.values()),
                        "rejections": suited.rejections, "seconds": time.perf_counter() - start})
    finally:
        generator.close()
    return out


def summary(values: list[int]) -> dict:
    return {"min": int(min(values)), "median": float(np.median(values)), "max": int(max(values)),
            "histogram": dict(sorted(collections.Counter(values).items()))} if values else {}


def main() -> None:
    from muble.generation.task_mix import template_weights
    from muble.io.instructions_io import SHOPVRB2_TEMPLATES

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=1000)
    parser.add_argument("--split", default="val")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--templates", nargs="*", default=list(SHOPVRB2_TEMPLATES))
    parser.add_argument("--weights", nargs="*", type=float, default=[], help="as dataset.template_weights")
    parser.add_argument("--reach-check", action="store_true", help="also run the generator's grasp check")
    args = parser.parse_args()
    weights = template_weights(args.templates, args.weights)
    target = {t: w / sum(weights) for t, w in zip(args.templates, weights)}

    chunks = [list(range(k, args.scenes, args.workers)) for k in range(args.workers)]
    jobs = [(args.seed, args.split, c, args.reach_check, args.templates, weights) for c in chunks if c]
    start = time.perf_counter()
    if len(jobs) == 1:
        records = _worker(jobs[0])
    else:
        with multiprocessing.get_context("spawn").Pool(len(jobs)) as pool:
            records = [r for chunk in pool.map(_worker, jobs) for r in chunk]
    wall = time.perf_counter() - start
    records.sort(key=lambda r: r["index"])

    n = len(records)
    counts = collections.Counter(r["template"] for r in records)
    shares = {t: counts[t] / n for t in args.templates}
    deviation = max(abs(shares[t] - target[t]) * 100 for t in args.templates)
    objects = collections.Counter(str(r["objects"]) for r in records)
    words = [r["words"] for r in records]
    plans = [r["plan"] for r in records]
    plans_by = {t: summary([r["plan"] for r in records if r["template"] == t]) for t in args.templates}
    for t in args.templates:
        p = plans_by[t]
        print(f"{t:24s} {counts[t]:5d} scenes  {100 * shares[t]:5.1f}% (target {100 * target[t]:.1f}%)  "
              f"plan {p.get('min')}-{p.get('max')} (median {p.get('median')})")
    print(f"objects per scene: {dict(sorted(objects.items()))} (paper: 47.3% / 52.7%)")
    print(f"words: {min(words)}-{max(words)} (paper 5-16); plans: {min(plans)}-{max(plans)} (paper 5-46)")
    per_scene = [r["seconds"] for r in records]
    print(json.dumps({
        "benchmark": "dataset_stats", "metric": "largest template share deviation from its target",
        "value": round(deviation, 2), "unit": "percentage points", "goal": GOAL_POINTS,
        "scenes": n, "split": args.split, "seed": args.seed, "reach_check": args.reach_check,
        "template_share": {t: round(shares[t], 4) for t in args.templates},
        "template_target": {t: round(target[t], 4) for t in args.templates},
        "objects": {k: round(v / n, 4) for k, v in sorted(objects.items())},
        "words": summary(words), "plan_primitives": summary(plans),
        "plan_primitives_by_template": {t: {k: v for k, v in p.items() if k != "histogram"}
                                        for t, p in plans_by.items()},
        "scene_samples": summary([r["samples"] for r in records]),
        "layouts_per_scene": {k: v for k, v in summary([r["layouts"] for r in records]).items() if k != "histogram"},
        "layouts_rejected": dict(sum((collections.Counter(r["rejections"]) for r in records), collections.Counter())),
        "seconds_per_scene_median": round(float(np.median(per_scene)), 3),
        "seconds_per_scene_mean": round(float(np.mean(per_scene)), 3),
        "workers": len(jobs), "wall_seconds": round(wall, 1), "paper": PAPER,
    }))


if __name__ == "__main__":
    main()

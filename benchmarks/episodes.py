"""Episode throughput of the evaluation loop: oracle episodes per hour, without rendering and with MuJoCo keyframes.

The same generated scenes and instructions (templates drawn from the full SHOP-VRB2 mix) run twice through
``EpisodeRunner``: once with no renderer (the ``muble eval`` default, the baseline) and once rendering a
848x480 RGB + depth + segmentation keyframe after every primitive with the MuJoCo renderer (what ``muble
generate`` records). Time is split into physics (primitives' control loops, straight-line IK included),
sampling-based planning and rendering.

Goal: 120 episodes per hour per worker without rendering (30 s per episode). At that rate one worker evaluates
the paper's 1000-episode test split in about 8 h and a 16-core machine in about 30 min, so a full benchmark run
fits a working session; the render overhead is reported so the cost of keyframes is visible beside it.

    python benchmarks/episodes.py [EPISODES]
"""
from __future__ import annotations

import json
import logging
import os
import sys
import time

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")


def setup(episodes: int):
    from muble.app.config import compose
    from muble.episode.components import build_components, scene_generator
    from muble.episode.runner import instruction_rng
    from muble.generation.task_mix import choose_from_mix as choose_instruction
    from muble.io.instructions_io import SHOPVRB2_TEMPLATES
    from muble.plugins.registry import get_registry

    cfg = compose("run", ["output.dir=/tmp", "dataset.root=/tmp"])
    components = build_components(cfg)
    registry = get_registry()
    tasks = [registry.create("task", name, {}) for name in SHOPVRB2_TEMPLATES]
    weights = np.full(len(tasks), 1.0 / len(tasks))
    generator = scene_generator(cfg, components["object_set"])
    work, planned = [], []
    try:
        for index in range(episodes):
            scene = generator.generate(index)
            task, instruction = choose_instruction(tasks, weights, scene, instruction_rng(cfg.seed, index))
            work.append((scene, instruction, task))
            planned.append(len(task.ground_truth(instruction, scene)))
    finally:
        generator.close()
    return cfg, components, work, planned


def run_mode(cfg, components, work, render: bool) -> dict:
    from muble.episode.components import episode_runner

    runner = episode_runner(cfg, {**components, "renderer": components["renderer"] if render else None})
    parts = {"physics": 0.0, "planning": 0.0, "rendering": 0.0, "total": 0.0}
    outcomes, primitives, keyframes = [], 0, 0
    start = time.perf_counter()
    for scene, instruction, task in work:
        output = runner.execute(scene, instruction, task)
        for part in parts:
            parts[part] += getattr(output.timing, part)
        outcomes.append(output.result.outcome.value)
        primitives += len(output.result.actions)
        keyframes += len(output.keyframes)
    wall = time.perf_counter() - start
    n = len(work)
    return {"episodes_per_hour": 3600.0 * n / wall, "seconds_per_episode": wall / n,
            "split_seconds_per_episode": {k: round(v / n, 3) for k, v in parts.items()},
            "split_fraction": {k: round(v / parts["total"], 3) for k, v in parts.items() if k != "total"},
            "primitives": primitives, "seconds_per_primitive": wall / max(primitives, 1), "keyframes": keyframes,
            "successes": outcomes.count("success"), "outcomes": outcomes}


def main() -> None:
    logging.basicConfig(level=logging.WARNING)
    episodes = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    cfg, components, work, planned = setup(episodes)
    run_mode(cfg, components, work[:1], render=False)  # warm-up: imports, OMPL, first model compile
    plain = run_mode(cfg, components, work, render=False)
    rendered = run_mode(cfg, components, work, render=True)
    templates = [instruction.template_id for _, instruction, _ in work]
    # Failed episodes stop early; the rate at the ground-truth length tells what complete episodes would cost.
    full_length = float(np.mean(planned))
    for r in (plain, rendered):
        r["episodes_per_hour_at_ground_truth_length"] = round(3600.0 / (r["seconds_per_primitive"] * full_length), 1)
    for name, r in (("no rendering", plain), ("MuJoCo keyframes", rendered)):
        s = r["split_seconds_per_episode"]
        print(f"{name:17s}: {r['episodes_per_hour']:6.0f} episodes/h  ({r['seconds_per_episode']:.1f} s/episode: "
              f"physics {s['physics']:.1f}, planning {s['planning']:.1f}, rendering {s['rendering']:.1f}); "
              f"{r['successes']}/{episodes} successes, {r['primitives']} primitives, {r['keyframes']} keyframes; "
              f"{r['episodes_per_hour_at_ground_truth_length']:.0f} episodes/h at the ground-truth length "
              f"({full_length:.1f} primitives)")
    print(json.dumps({
        "benchmark": "episodes", "metric": "oracle episodes per hour per worker, no rendering",
        "value": round(plain["episodes_per_hour"], 1), "unit": "episodes/h", "goal": 120,
        "baseline": "no rendering; with_keyframes renders 848x480 RGB+depth+segmentation after every primitive",
        "with_keyframes": round(rendered["episodes_per_hour"], 1),
        "render_overhead": round(rendered["seconds_per_episode"] / plain["seconds_per_episode"] - 1.0, 3),
        "no_rendering_at_ground_truth_length": plain["episodes_per_hour_at_ground_truth_length"],
        "episodes": episodes, "ground_truth_primitives": planned, "templates": templates, "no_rendering": plain, "keyframes": rendered,
        "cores": os.cpu_count(),
    }))


if __name__ == "__main__":
    main()

"""Instruction generation throughput on one core, plus the acceptance statistics over 1,000 sampled scenes.

The statistics (words per instruction, ground-truth primitives per plan, oracle success in the symbolic
world) cover every generated instruction.

Run from the repository root: ``python benchmarks/instructions.py [--scenes 1000]``. Timings cover generation
only (descriptions with their ambiguity checks, option rejection, text, program with recorded outputs), on
scenes sampled beforehand. The anchor is the original MuBlE generator run on this machine type on its ten demo
scenes repeated 50 times: 4,032 instructions in 1.21 s wall, interpreter start included (about 3,300/s).
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import time
from pathlib import Path

import numpy as np

from muble import Outcome
from muble.core import streams
from muble.io.scene_io import load_scenes
from muble_plugins.agents.oracle import OracleAgent
from muble_plugins.common.episodes import run_symbolic_episode
from muble_plugins.common.synthetic import sample_scenes
from muble_plugins.tasks.generator import generate_instructions
from muble_plugins.tasks.templates import TEMPLATES

ANCHOR_PER_S = 4032 / 1.21
GOAL_PER_S = 5000
REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "muble-demo" / "NS_AP_demo_scenes.json"


INSTRUCTIONS = streams.declare("bench.instructions", "the instructions generated for a scene (repeat, scene index)")


def throughput(scenes, seed: int, repeats: int = 1) -> tuple[int, float]:
    start = time.perf_counter()
    made = 0
    for r in range(repeats):
        for s in scenes:
            made += len(generate_instructions(s, streams.stream(INSTRUCTIONS, seed, r, s.image_index)))
    return made, time.perf_counter() - start


def summary(values: list[int]) -> dict:
    if not values:
        return {}
    return {"min": int(min(values)), "median": float(np.median(values)), "max": int(max(values)),
            "histogram": dict(sorted(collections.Counter(values).items()))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core

    scenes = sample_scenes(args.seed, args.scenes)
    throughput(scenes[:20], args.seed)  # warm caches and imports
    made, seconds = throughput(scenes, args.seed)
    reference_rate = None
    if REFERENCE.is_file():
        _, demo = load_scenes(REFERENCE)
        ref_made, ref_seconds = throughput(demo, args.seed, repeats=50)
        reference_rate = ref_made / ref_seconds

    # Acceptance statistics over every scene: words, plan lengths, templates per scene, oracle outcomes.
    words: dict[str, list[int]] = collections.defaultdict(list)
    plan_lengths: dict[str, list[int]] = collections.defaultdict(list)
    scenes_with: collections.Counter = collections.Counter()
    oracle: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for s in scenes:
        for ins in generate_instructions(s, streams.stream(INSTRUCTIONS, args.seed, 0, s.image_index)):
            t = ins.template_id
            scenes_with[t] += 1
            words[t].append(len(ins.instruction.split()))
            episode = run_symbolic_episode(ins, s, OracleAgent())
            oracle[t][episode.outcome.value] += 1
            if episode.outcome is Outcome.SUCCESS:
                plan_lengths[t].append(len(episode.actions))
    all_words = [w for v in words.values() for w in v]
    all_plans = [n for v in plan_lengths.values() for n in v]
    success = {t: oracle[t]["success"] / max(1, oracle[t].total()) for t in TEMPLATES}
    for t in TEMPLATES:
        print(f"{t:24s} scenes {scenes_with[t]:5d}  words {summary(words[t]).get('min')}-"
              f"{summary(words[t]).get('max')}  plan {summary(plan_lengths[t]).get('min')}-"
              f"{summary(plan_lengths[t]).get('max')}  oracle {success[t]:.3f} of {oracle[t].total()}")
    print(json.dumps({
        "benchmark": "instructions", "metric": "instructions per second (one core, ambiguity checks on)",
        "value": round(made / seconds, 1), "unit": "instructions/s", "goal": GOAL_PER_S,
        "scenes": len(scenes), "instructions": made, "seconds": round(seconds, 3),
        "reference_scenes_x50_per_s": round(reference_rate, 1) if reference_rate else None,
        "anchor_original_per_s": round(ANCHOR_PER_S, 1),
        "scenes_with_template": dict(scenes_with),
        "words": summary(all_words), "plan_primitives": summary(all_plans),
        "plan_primitives_by_template": {t: {k: v for k, v in summary(plan_lengths[t]).items() if k != "histogram"}
                                        for t in TEMPLATES},
        "oracle_symbolic_success": success,
    }))


if __name__ == "__main__":
    main()
